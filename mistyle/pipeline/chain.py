"""The product: density + style -> network -> colour match -> refinement -> path tracing, in memory.

    from mistyle.pipeline import Pipeline, PipelineSettings

    pipeline = Pipeline(PipelineSettings())                 # the bundled checkpoint, mistyle-render's defaults
    stylized = pipeline.stylize(density, "marble.png")      # Stylization: .albedos[0] is what gets path traced
    images, _ = pipeline.path_trace(stylized.frames, stylized.albedos)   # the final images, linear RGB

The chain, each stage owned by one module and configured by ``PipelineSettings``:

1. **Network** (``Stylizer``): the SKPN's albedo for each frame, from the style's stylizing kernels
   (mixed and weakened on the kernels: ``Stylizer.kernels``, ``Stylizer.weakened``).
2. **Colour match** (``mistyle.colour_match``): the network's arrangement with the style's colours;
   a sequence shares the map fitted on its first frame the layer sees.
3. **A look, or refinement.** By default (full strength, the colour match on, no refinement steps
   named) a look is fitted on the frame, or on a sequence's key frames, and applied to every frame
   (``Pipeline.fits_look``, ``mistyle.look``). Otherwise, when the settings name steps,
   refinement (``fit.refine_albedo``): fast-layer steps, then path-traced steps, against the style;
   in a sequence each frame starts from the previous frame's result warped by the velocity and is
   held near it by the temporal term. ``Pipeline.refinement`` owns the rule for how many steps.
   A grid longer than the settings' ``working_size`` on any side goes through stages 1-3 as a copy
   resampled to it, and its albedo comes back to the full grid (``mistyle.resample``).
4. **Path tracing** (``pathtrace.path_trace``): Mitsuba's ``volpath``, multiple scattering, in passes
   (a stop waits for one pass). A render that cannot show the medium is refused with its cause: before
   any work when the inputs decide it (``Pipeline.check_visible``), else after it (``check_images``).

``mistyle-render`` is argparse -> ``PipelineSettings`` -> ``Pipeline`` -> files, and
``mistyle.stylize(..., refine=True)`` returns the albedo it path traces by default
(``tests/test_pipeline.py`` checks that the two agree bit for bit).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ..style import Style
from ..stylizer import Stylizer, check_finite, checked_frames
from .frames import Frames, Stylization, flicker_report
from .settings import PipelineSettings, default_refinement, described


class Pipeline:
    """The chain of the module docstring for one set of ``PipelineSettings``, network loaded once.

    ``log(message)``, when given, receives a status line per stage (the command line prints them);
    progress bars appear on a terminal only (``mistyle.progress``).
    """

    def __init__(
        self,
        settings: PipelineSettings | None = None,
        stylizer: Stylizer | None = None,
        log: Callable[[str], None] | None = None,
    ):
        if settings is not None and not isinstance(settings, PipelineSettings):
            raise TypeError(
                f"settings must be a PipelineSettings (e.g. Pipeline(PipelineSettings(strength=0.5))) or None, "
                f"got {described(settings)}."
            )
        if stylizer is not None and not isinstance(stylizer, Stylizer):
            raise TypeError(
                f"stylizer must be a Stylizer (loaded once, shared by pipelines) or None, got {described(stylizer)}."
            )
        if log is not None and not callable(log):
            raise TypeError(f"log must be a function of one message (e.g. print) or None, got {described(log)}.")
        self.settings = settings if settings is not None else PipelineSettings()
        s = self.settings
        self.stylizer = stylizer if stylizer is not None else Stylizer(s.checkpoint, s.device, s.vgg_weights)
        self.log = log if log is not None else (lambda message: None)

    @property
    def config(self):
        return self.stylizer.config

    @property
    def density_scale(self) -> float:
        s = self.settings
        return s.density_scale if s.density_scale is not None else self.stylizer.density_scale

    @property
    def camera_distance(self) -> float:
        s = self.settings
        return s.camera_distance if s.camera_distance is not None else self.config.render.camera_distance

    @property
    def radiance(self) -> float:
        """The training light's radiance: the constant environment of refinement and of ``light`` by default."""
        return self.config.render.radiance

    def light(self):
        """The final render's ``scenes.LightSpec``; ``ValueError`` for an environment map holding NaN/inf
        pixels (``pathtrace.check_light``), before anything is read or rendered."""
        from ..pathtrace import check_light
        from ..scenes import LightSpec

        light = LightSpec.parse(self.settings.render.light, default_radiance=self.radiance)
        check_light(light)
        return light

    def views(self) -> list:
        """The final render's ``scenes.View``s: one at ``render.view``, or a turntable from it."""
        from ..scenes import CameraPath

        render = self.settings.render
        orbit = CameraPath(distance=self.camera_distance)
        return orbit.turntable(render.turntable, offset=render.view) if render.turntable else [orbit.view(render.view)]

    def fits_look(self) -> bool:
        """``PipelineSettings.fits_look`` of this pipeline's settings."""
        return self.settings.fits_look

    def refinement(self, frames: int = 1):
        """The refinement schedule (``fit.RefineSettings``) for ``frames`` frames.

        Steps the settings name are used as they are. Otherwise none when a look is fitted instead
        (``fits_look``); a single frame without the colour match gets ``default_refinement``'s steps;
        sequences and weakened styles get none: even warm-started and anchored, refined frames
        flicker about twice as much as the network's and each frame costs the refinement's time, and
        refining against the style would undo a strength below 1. ``refine_steps=0`` also turns the
        path-traced steps off unless they are named."""
        s = self.settings
        defaults = default_refinement(self.config, self.camera_distance)
        unrefined = frames > 1 or s.strength < 1.0 or self.fits_look()
        layer = s.refine_steps if s.refine_steps is not None else 0 if unrefined else defaults.layer_steps
        path = (
            s.refine_path_steps
            if s.refine_path_steps is not None
            else 0
            if unrefined or s.refine_steps == 0
            else defaults.path_steps
        )
        return replace(defaults, layer_steps=layer, path_steps=path)

    def look_refinement(self):
        """The refinement of frames stylized from a look: only the steps the settings name (a look is
        fitted not to need any, and each frame must stay independent of the others)."""
        s = self.settings
        return replace(self.refinement(1), layer_steps=s.refine_steps or 0, path_steps=s.refine_path_steps or 0)

    def frames(self, density, velocities=None, names=None, motion=None, first: int = 0, chunk: bool = False) -> Frames:
        """``density`` as ``Frames``: one ``(Z, Y, X)`` array, a sequence ``(T, Z, Y, X)`` or a list of
        frames; ``velocities`` ``(Z, Y, X, 3)`` per frame or None; ``names``: the frames' names in
        messages; ``motion`` (``advection.TextureMotion``) and ``first``: for frames ``first`` on of a
        longer sequence, the velocities of the frames before them that a look's texture follows
        (default: ``velocities``'). ``ValueError`` for a frame that is not a valid density, or a single
        frame that holds too little medium. A sequence's frames may hold too little as long as one holds
        enough (all of them in a ``chunk``, frames of a longer sequence): they are rendered as they are
        (``Frames.filled``)."""
        if isinstance(density, Frames):
            return density
        grids, _ = checked_frames(density, names, chunk)
        if len({grid.shape for grid in grids}) > 1:
            raise ValueError(
                f"The frames have different shapes {sorted({g.shape for g in grids})}; a sequence needs one grid size."
            )
        if velocities is not None and len(velocities) != len(grids):
            raise ValueError(f"Need one velocity per frame, got {len(velocities)} for {len(grids)} frames.")
        if velocities is not None and motion is None and len(grids) > 1:
            from ..advection import TextureMotion

            motion = TextureMotion(list(velocities), begin=first)
        return Frames(grids, None if velocities is None else list(velocities), self.density_scale, motion, first)

    # ------------------------------------------------------------------------ stylize
    def stylize(self, density, style, velocities=None, notes: list | None = None) -> Stylization:
        """Network, colour match and refinement for every frame of ``density``.

        ``style``: an image or path, a mix ``[(image or path, weight)]`` (see ``style_parts``), or a ``Style``.
        ``notes`` (a list) collects what the user should know (conversions, skipped stages)."""
        s = self.settings
        notes = [] if notes is None else notes
        full = self.frames(density, velocities)
        self.check_visible(full)
        frames = self.working_frames(full, notes)
        style = Style.of(style, notes)
        refinement = self.refinement(len(frames.densities))
        if s.strength < 1.0 and s.refine_steps is None:
            notes.append(
                f"strength {s.strength:g}: not refined against the style (which would undo the strength); "
                "name the refinement steps to refine anyway"
            )
        report: dict = {}

        self.note_empty_frames(frames, notes)
        started = time.perf_counter()
        stacked = np.stack(frames.densities) if frames.sequence else frames.densities[0]
        network = self.stylizer(
            stacked,
            style,
            s.scale_structures,
            notes=notes,
            strength=s.strength,
            match_colours=s.colour_match,
            density_scale=self.density_scale,
            camera_distance=self.camera_distance,
        )
        network = list(network) if frames.sequence else [network]
        report["stylize_seconds"] = time.perf_counter() - started
        check_finite("The network's albedo of frame", network)
        self.log(
            f"stylized {len(network)} frame(s) of {frames.densities[0].shape} in {report['stylize_seconds']:.2f} s"
        )
        report.update(flicker_report(network, frames))
        if frames.sequence and frames.velocities is None:
            notes.append("the frames carry no velocity; temporal_flicker*_unwarped compares frames without warping")

        albedos, look = network, None
        if self.fits_look():
            from ..look import LookSettings
            from ..progress import bar, fit_progress

            started = time.perf_counter()
            with bar(LookSettings().steps if s.look_steps is None else s.look_steps, "fitting a look") as progress_bar:
                look = self.default_look(frames, style, notes=notes, progress=fit_progress(progress_bar))
            albedos = frames.filled([look.apply(frames.densities[i], frames.phases(i)) for i in frames.holding])
            report["look_seconds"] = time.perf_counter() - started
            report["look_key_frames"] = look.meta["key_frames"]
            report.update(flicker_report(albedos, frames, "_look"))
            fitted_on = f"key frames {', '.join(map(str, look.meta['key_frames']))}" if frames.sequence else "the frame"
            seconds = report["look_seconds"]
            self.log(f"fitted a look on {fitted_on} and applied it to {len(albedos)} frame(s) in {seconds:.1f} s")
        elif refinement.layer_steps or refinement.path_steps:
            albedos, report["refine_seconds"] = self.refine(frames, albedos, style.target, refinement)
            report.update(flicker_report(albedos, frames, "_refined"))
        check_finite("The corrected albedo of frame", albedos)
        network, albedos = self.full_albedos(frames, network, albedos, report)
        return Stylization(full, network, albedos, style.target, refinement, report, notes, look)

    def note_empty_frames(self, frames: Frames, notes: list) -> None:
        """Say in the log and ``notes`` which of ``frames`` are rendered without being stylized."""
        note = frames.empty_note()
        if note is not None:
            self.log(note)
            if note not in notes:
                notes.append(note)

    def working_frames(self, frames: Frames, notes: list | None = None) -> Frames:
        """``frames`` as they are stylized: their copy at the settings' ``working_size``
        (``Frames.at_working_size``), said in ``notes`` and the log when it is one."""
        work = frames.at_working_size(self.settings.working_size)
        if work is not frames:
            size = self.settings.working_size
            message = (
                f"{work.working_grid.describe()} at working size {size}, its albedo resampled back to the full "
                "grid for the path trace (working size 0 stylizes the full grid)"
            )
            self.log(message)
            if notes is not None and message not in notes:
                notes.append(message)
        return work

    def full_albedos(self, frames: Frames, network: list, albedos: list, report: dict) -> tuple[list, list]:
        """``(network, albedos)`` of the stylized ``frames`` on the full grid where ``frames`` are a working copy."""
        if frames.working_grid is None:
            return network, albedos
        started = time.perf_counter()
        full_network = frames.full_albedos(network)
        full_albedos = full_network if albedos is network else frames.full_albedos(albedos)
        report["working_shape"] = list(frames.densities[0].shape)
        report["resample_seconds"] = time.perf_counter() - started
        return full_network, full_albedos

    def default_look(self, density, style, notes: list | None = None, progress=None):
        """The look the default output fits (``fits_look``) on ``density``'s frames: on the frame, or on a
        sequence's key frames (the settings' ``key_frames``, else ``look.default_key_frames``). The live
        preview fits this same look, so that what it shows is what ``mistyle-render`` writes."""
        from ..look import parse_key_frames

        frames = self.frames(density)
        keys = self.settings.key_frames
        keys = None if keys is None else parse_key_frames(keys, len(frames.densities))
        return self.fit_look(frames, style, key_frames=keys, notes=notes, progress=progress)

    def fit_look(
        self,
        density,
        style,
        key_frames=None,
        look_settings=None,
        notes: list | None = None,
        progress=None,
        style_names=None,
    ):
        """``look.fit_look`` on ``density``'s frames (a frame, a sequence or a list) with this pipeline's
        network, density scale, orbit and structure scale; ``key_frames`` default to the first, middle
        and last frame."""
        from ..look import LookSettings, fit_look

        if look_settings is None and self.settings.look_steps is not None:
            look_settings = LookSettings(steps=self.settings.look_steps)
        frames = self.working_frames(self.frames(density), notes)
        return fit_look(
            self.stylizer,
            frames.densities,
            style,
            key_frames=key_frames,
            density_scale=frames.density_scale,
            camera_distance=self.camera_distance,
            scale_structures=self.settings.scale_structures,
            settings=look_settings,
            notes=notes,
            progress=progress,
            style_names=style_names,
            prepared=frames.prepared,
        )

    def look_stylization(self, density, look, velocities=None, notes: list | None = None) -> Stylization:
        """Every frame of ``density`` stylized by ``look`` (``look.Look``): the look's tuned network and
        colour match on each frame's own density, no refinement unless the settings name steps (then
        each frame is refined on its own, from the look's albedo). The target is the look's style."""
        notes = [] if notes is None else notes
        full = self.frames(density, velocities)
        self.check_visible(full)
        frames = self.working_frames(full, notes)
        notes.extend(look.notes_for(frames.densities[0].shape, frames.density_scale))
        self.note_empty_frames(frames, notes)
        report: dict = {}
        started = time.perf_counter()
        network = frames.filled([look.apply(frames.densities[i], frames.phases(i)) for i in frames.holding])
        report["stylize_seconds"] = time.perf_counter() - started
        check_finite("The look's albedo of frame", network)
        self.log(f"stylized {len(network)} frame(s) from the look in {report['stylize_seconds']:.2f} s")
        report.update(flicker_report(network, frames))
        refinement = self.look_refinement()
        albedos = network
        if refinement.layer_steps or refinement.path_steps:
            # Each frame on its own: a chunk of a sequence must not depend on the frames before it.
            albedos, seconds = [], 0.0
            for index in range(len(network)):
                if index not in frames.holding:
                    albedos.append(network[index])
                    continue
                one = Frames([frames.densities[index]], None, frames.density_scale)
                refined, took = self.refine(one, [network[index]], look.style, refinement)
                albedos += refined
                seconds += took
            report["refine_seconds"] = seconds
        network, albedos = self.full_albedos(frames, network, albedos, report)
        return Stylization(full, network, albedos, look.style, refinement, report, notes)

    def refine(self, frames: Frames, albedos: list, target: np.ndarray, refinement) -> tuple[list, float]:
        """``fit.refine_albedo`` of every frame against ``target`` with the schedule ``refinement``:
        ``(refined albedos, seconds)``.

        In a sequence, each frame after the first starts from the previous frame's refined albedo
        warped by its velocity (unwarped when the frames carry none) and is held near it by the
        temporal term (``RefineSettings.temporal_weight``; experiments/sequence_refine.py measures
        the flicker)."""
        from ..fit import refine_albedo
        from ..progress import bar
        from ..warp import warp_grid

        refined, seconds = [], 0.0
        for index, (grid, albedo) in enumerate(zip(frames.densities, albedos)):
            if index not in frames.holding:  # before the emitter starts: nothing to refine
                refined.append(albedo)
                continue
            label = f"refining frame {index}" if frames.sequence else "refining"
            with bar(refinement.layer_steps + refinement.path_steps, label) as progress_bar:

                def progress(stage, done, count, loss, progress_bar=progress_bar):
                    progress_bar.set_postfix_str(f"{stage}, loss {loss:.4g}", refresh=False)
                    progress_bar.update(1)

                anchor = None
                if index - 1 in frames.holding:
                    previous = refined[-1]
                    anchor = (
                        warp_grid(previous, frames.velocities[index - 1]) if frames.velocities is not None else previous
                    )
                    albedo = anchor
                result, took = refine_albedo(
                    grid,
                    frames.density_scale,
                    albedo,
                    target,
                    refinement,
                    radiance=self.radiance,
                    device=self.settings.device,
                    prepared=frames.prepared(index),
                    anchor=anchor,
                    progress=progress,
                )
            self.log(
                f"{label}: {refinement.layer_steps} layer + {refinement.path_steps} path-traced steps in {took:.1f} s"
            )
            refined.append(result)
            seconds += took
        return refined, seconds

    # ------------------------------------------------------------------------ render
    def path_trace(
        self,
        frames: Frames,
        albedos: list,
        views: list | None = None,
        coat_mesh=None,
        progress=None,
        first: int = 0,
        notes: list | None = None,
        chunk: bool = False,
    ) -> tuple[list, list]:
        """Path-trace frame ``i`` with ``albedos[i]`` from ``views`` (default ``self.views()``): every view
        of a single frame, or for a sequence frame ``i`` from view ``i mod len(views)``. Returns
        ``(images (res, res, 3) linear RGB, seconds per image)``; ``progress(done, count, seconds)``
        after each image.

        ``ValueError`` naming the cause for images that cannot show the medium: before the render when
        the inputs decide it (``check_visible``; an albedo holding NaN/inf), after it for a NaN/inf image
        or one that shows the medium in too few pixels (``check_images``). In a sequence or a turntable
        an image that shows no medium while others do is a warning, logged and added to ``notes``; in a
        ``chunk`` of a sequence (``first`` > 0, or ``chunk``: rendered in parts, ``--frames``) even when
        none of its images does, since the other chunks may. The path tracer's scene is kept for the next
        call, unless the grid is larger than ``pathtrace.KEPT_SCENE_VOXELS``."""
        from ..denoise import denoise
        from ..pathtrace import KEPT_SCENE_VOXELS, path_trace, release_scenes

        render = self.settings.render
        plan = self.render_plan(frames, views, first)
        labels = self.image_labels(frames, plan, first)
        self.check_visible(frames, plan)
        for frame, _ in plan:
            bad = ~np.isfinite(np.asarray(albedos[frame], dtype=np.float32))
            if bad.any():
                where = tuple(int(i) for i in np.argwhere(bad)[0])
                name = f"frame {first + frame}" if len(plan) > 1 or first else "the frame"
                raise ValueError(
                    f"The albedo of {name} holds {int(bad.sum())} NaN/inf value(s) (first at [z, y, x, channel] = "
                    f"{where}), which the path tracer cannot render. Clean it (e.g. np.nan_to_num(albedo, nan=0.5)) "
                    "or check what made it (the look, the refinement)."
                )
        images, seconds = [], []
        for frame, frame_views in plan:
            frame_images, took = path_trace(
                frames.densities[frame],
                albedos[frame],
                frame_views,
                coat_mesh=coat_mesh,
                progress=progress,
                **self.trace_options(),
            )
            for offset, image in enumerate(frame_images):  # before the denoiser, which hides NaN
                self.check_finite_render(image, labels[len(images) + offset])
            if render.denoise == "oidn":
                started = time.perf_counter()
                frame_images = [denoise(image) for image in frame_images]
                took = [t + (time.perf_counter() - started) / len(took) for t in took]
            images += frame_images
            seconds += took
        if frames.densities[0].size > KEPT_SCENE_VOXELS:
            release_scenes()  # its frames are traced: the next ones (a chunk, an output) rebuild it
        check_finite("The path-traced image", images)
        self.check_images(images, frames, albedos, plan, labels, notes, refuse=not (chunk or first))
        return images, seconds

    def image_labels(self, frames: Frames, plan: list, first: int = 0) -> list[str]:
        """What messages call each image of ``plan`` (``render_plan``): ``the final image``, ``view i``
        of a turntable, ``frame i`` of a sequence (its index in the whole sequence)."""
        if frames.sequence or first:
            return [f"frame {first + frame}" for frame, _ in plan]
        ((_, views),) = plan
        return ["the final image"] if len(views) == 1 else [f"view {index}" for index in range(len(views))]

    def check_visible(self, frames: Frames, plan: list | None = None) -> None:
        """``ValueError`` before any work for a final render that cannot show the medium, as far as the
        settings and the densities decide it: ``max_depth`` 1 (``pathtrace.check_max_depth``), an
        environment map holding NaN/inf (``light``), a camera from which the medium spans too few pixels
        or a medium too thin for the light to show (``pathtrace.unseen_medium``). For a sequence or
        a turntable only when no image can show it: a simulation may start as a wisp, which
        ``check_images`` reports after the render. Also a medium so dense that the path tracer's time is
        out of bounds (``volume.validate_extinction``)."""
        from ..pathtrace import check_max_depth, unseen_medium
        from ..volume import validate_extinction

        render = self.settings.render
        check_max_depth(render.max_depth)
        for index, density in enumerate(frames.densities):
            validate_extinction(density, frames.density_scale, f"Frame {index}" if frames.sequence else "The density")
        light = self.light()
        plan = self.render_plan(frames) if plan is None else plan
        plan = [(frame, views) for frame, views in plan if frame in frames.holding]  # empty frames show nothing
        causes = [
            unseen_medium(frames.densities[frame], view, render.res, frames.density_scale, light)
            for frame, views in plan
            for view in views
        ]
        if causes and all(causes):
            self.refuse_unseen(self.image_labels(frames, plan), causes, "cannot show the", "can show the")

    def check_finite_render(self, image: np.ndarray, label: str) -> None:
        """``ValueError`` for a path-traced image holding NaN/inf, which its finite inputs (density, albedo
        and light, all checked) should never give."""
        bad = ~np.isfinite(image).all(axis=-1)
        if bad.any():
            render = self.settings.render
            row, column = (int(i) for i in np.argwhere(bad)[0])
            raise ValueError(
                f"The path tracer gave {label} {int(bad.sum())} NaN/inf pixel(s) (first at row {row}, column "
                f"{column}) from finite inputs: light {render.light!r}, density scale {self.density_scale:g}, max "
                f"depth {render.max_depth}. Nothing was written; try a lower density scale or light strength."
            )

    def check_images(
        self,
        images: list,
        frames: Frames,
        albedos: list,
        plan: list,
        labels: list[str],
        notes: list | None = None,
        refuse: bool = True,
    ) -> None:
        """After the render: ``ValueError`` naming the cause (``pathtrace.dark_render``: the medium too thin,
        its albedo black, the camera too far, the light) when no image shows the medium in enough pixels
        and ``refuse``. Otherwise (a sequence that starts as a wisp, a turntable, a chunk) each image that
        does not is a warning on the console (``log``) and in ``notes``."""
        from ..pathtrace import dark_render

        render = self.settings.render
        light = self.light()
        pairs = [(frame, view) for frame, views in plan for view in views]
        # A frame with too little medium to stylize shows next to nothing, as it should (Frames.empty_note).
        held = [index for index, (frame, _) in enumerate(pairs) if frame in frames.holding]
        causes = [None] * len(pairs)
        for index in held:
            frame, view = pairs[index]
            density, scale = frames.densities[frame], frames.density_scale
            causes[index] = dark_render(images[index], density, albedos[frame], view, render.res, scale, light)
        if refuse and held and all(causes[index] for index in held):
            self.refuse_unseen([labels[i] for i in held], [causes[i] for i in held], "shows no", "shows the")
        for label, cause in zip(labels, causes):
            if cause:
                warning = f"{label} shows no medium: {cause}"
                self.log(f"warning: {warning}")
                if notes is not None:
                    notes.append(warning)

    @staticmethod
    def refuse_unseen(labels: list[str], causes: list[str], one: str, none_of: str) -> None:
        """The ``ValueError`` for a render none of whose images shows the medium, with the first one's
        cause: "The final image {one} medium: ..." or "None of the N images {none_of} medium; ..."."""
        if len(labels) == 1:
            raise ValueError(f"The final image {one} medium: {causes[0]} Nothing was written.")
        raise ValueError(
            f"None of the {len(labels)} images {none_of} medium; {labels[0]}: {causes[0]} Nothing was written."
        )

    def render_plan(self, frames: Frames, views: list | None = None, first: int = 0) -> list[tuple[int, list]]:
        """``(frame, views)`` to path trace: every view of one frame, or each frame of a sequence
        from the views in turn; ``first``: the index of ``frames``' first frame in the whole sequence
        (a chunk's frames take the views the whole sequence would give them)."""
        views = self.views() if views is None else views
        if frames.sequence or first:
            return [(i, [views[(first + i) % len(views)]]) for i in range(len(frames.densities))]
        return [(0, views)]

    def trace_options(self) -> dict:
        """``pathtrace.path_trace``'s options for the final render (also the exported scene's)."""
        render = self.settings.render
        return {
            "res": render.res,
            "spp": render.spp,
            "max_depth": render.max_depth,
            "density_scale": self.density_scale,
            "light": self.light(),
            "coat_ior": render.coat_ior,
            "device": self.settings.device,
            "bricks": render.bricks,
        }

    def layer_images(self, frames: Frames, frame: int, albedo: np.ndarray, views: list) -> list[np.ndarray]:
        """The fast layer's images ``(res, res, 3)`` of ``albedo`` on ``frame`` under the training light; of
        the working copy (``working_frames``) where the frames have one."""
        import torch

        from ..bridge_torch import render_views

        work = frames.at_working_size(self.settings.working_size)
        if work is not frames:
            albedo = work.working_grid.working_albedo(albedo, frames.densities[frame])
            frames = work
        grid = torch.from_numpy(albedo).permute(3, 0, 1, 2).to(self.settings.device)
        with torch.no_grad():
            images = render_views(
                grid,
                frames.prepared(frame),
                views,
                self.settings.render.res,
                steps=self.config.render.steps,
                radiance=self.radiance,
            )
        images = [image.permute(1, 2, 0).cpu().numpy() for image in images]
        check_finite("The fast layer's image", images)
        return images
