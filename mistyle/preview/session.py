"""What the live preview shows, without the web: a density (or sequence), a set of styles, the
controls' state, and the images of that state.

``PreviewSession`` owns the chain an artist tweaks interactively: the network's kernels for the chosen
style (or a mix of two), weakened to the chosen strength, the colour match fitted on the first frame,
the fast layer's image from the orbiting camera while the user interacts, and path-traced passes
that refine into a progressive image when the view is still. Where *Render final output* fits a look
(full strength, ``PipelineSettings.fits_look`` of the page's render options), the session fits that
same look (``Pipeline.default_look``, with the settings the render is given) and shows it once it is
fitted: what the page shows is then what the render writes. Everything it computes is cached by the
part of the state it depends on, so a camera move only renders, a frame change only runs the
network (or the look) on that frame, and a style change runs the network and the colour match once.

It is not thread-safe: the server (``mistyle.preview.server``) calls it from one worker thread, the
one that owns Mitsuba and torch.
"""

from __future__ import annotations

import io
import math
import tempfile
import time
from collections import OrderedDict
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..conventions import HELD_OUT_VIEW, MIN_CAMERA_DISTANCE, ORBIT_DISTANCE
from ..stylizer import empty_frame_albedo, holding_frames, holds_medium

THUMBNAIL_SIDE = 96
MAX_UPLOAD_BYTES = 64 * 1024 * 1024
"""An upload larger than this is refused before decoding (the decoder's own limits apply after)."""
LAYER_STEPS = 48
"""Ray-marching segments of the interactive image: the look fit's count, enough at 256^2 for a preview."""
PASS_SPP = 2
"""Samples per pixel of each path-traced pass of the progressive image: a pass (about 0.2 s at 256^2 here) is
what a control change may wait for."""
MAX_PATH_SPP = 256
MAX_CAMERA_DISTANCE = 8.0
JPEG_QUALITY = 85
MAX_FITTED_LOOKS = 4
"""Fitted looks a session keeps (one per style or mix it was shown at full strength)."""


@dataclass(frozen=True)
class Camera:
    """An orbit camera around the medium box's centre (+y up): azimuth and elevation in radians."""

    azimuth: float = 2.0 * math.pi * HELD_OUT_VIEW
    elevation: float = math.radians(10.0)
    distance: float = ORBIT_DISTANCE  # the session starts at its checkpoint's orbit (initial_controls)

    def clamped(self) -> Camera:
        return Camera(
            float(self.azimuth) % (2.0 * math.pi),
            float(np.clip(self.elevation, -1.45, 1.45)),
            float(np.clip(self.distance, MIN_CAMERA_DISTANCE + 0.05, MAX_CAMERA_DISTANCE)),
        )

    def view(self):
        from ..scenes import View

        c = math.cos(self.elevation)
        origin = self.distance * np.array(
            [c * math.sin(self.azimuth), math.sin(self.elevation), c * math.cos(self.azimuth)]
        )
        return View(origin=tuple(origin))


@dataclass(frozen=True)
class Controls:
    """The state an artist sets: ``style`` and ``mix_with`` index ``PreviewSession.styles``; ``mix`` is the
    second style's share; ``look`` applies the session's look instead of the styles."""

    style: int = 0
    mix_with: int | None = None
    mix: float = 0.5
    strength: float = 1.0
    frame: int = 0
    look: bool = False
    camera: Camera = Camera()

    @property
    def style_key(self) -> tuple:
        """What the albedo depends on besides the frame."""
        if self.look:
            return ("look",)
        mix = self.mix if self.mix_with is not None else 0.0
        return (self.style, self.mix_with if mix > 0 else None, round(mix, 4), round(self.strength, 4))


def mix_weights(mix: float) -> tuple[float, float]:
    """The weights of a mix's two styles: the first style's share and the second's ``mix``."""
    return 1.0 - mix, mix


@dataclass
class StyleOption:
    """A style the page offers: its name, its picture and the thumbnail the page shows."""

    name: str
    image: np.ndarray  # (H, W, 3) float32 display RGB, decoded by io.load_style
    thumbnail: bytes  # JPEG


def thumbnail_jpeg(image: np.ndarray, side: int = THUMBNAIL_SIDE) -> bytes:
    from PIL import Image

    picture = Image.fromarray((np.clip(image, 0, 1) * 255 + 0.5).astype(np.uint8))
    picture.thumbnail((side, side), Image.LANCZOS)
    buffer = io.BytesIO()
    picture.save(buffer, format="JPEG", quality=JPEG_QUALITY)
    return buffer.getvalue()


def jpeg(image: np.ndarray) -> bytes:
    """A linear ``(H, W, 3)`` radiance image on the renders' display curve, as JPEG bytes."""
    from PIL import Image

    from ..tone import display

    buffer = io.BytesIO()
    Image.fromarray((display(image) * 255 + 0.5).astype(np.uint8)).save(buffer, format="JPEG", quality=JPEG_QUALITY)
    return buffer.getvalue()


def decode_upload(name: str, data: bytes) -> StyleOption:
    """An uploaded picture through the decoder and limits of ``--style`` (``io.load_style``).

    Raises:
        ValueError: too large, or not a picture the decoder takes (its message says why)."""
    from ..files import load_style

    if len(data) > MAX_UPLOAD_BYTES:
        raise ValueError(f"{name} is {len(data) / 2**20:.0f} MB; uploads are limited to {MAX_UPLOAD_BYTES >> 20} MB.")
    suffix = Path(name).suffix.lower() or ".png"
    with tempfile.TemporaryDirectory(prefix="mistyle-upload-") as folder:
        path = Path(folder) / f"upload{suffix}"
        path.write_bytes(data)
        try:
            image = load_style(path)
        except ValueError as error:
            raise ValueError(str(error).replace(str(path), name)) from None
    return StyleOption(Path(name).name, image, thumbnail_jpeg(image))


class PreviewSession:
    """A density's frames, the styles, and the images of ``Controls`` (module docstring)."""

    def __init__(
        self,
        pipeline,
        frames: list[np.ndarray],
        styles: list[StyleOption],
        *,
        look=None,
        res: int = 256,
        velocities=None,
    ):
        """``pipeline``: a ``pipeline.Pipeline`` with the settings of the page's final renders (its network,
        density scale, orbit and look settings are the preview's); ``look``: a loaded ``look.Look`` the
        page can apply; ``velocities``: the frames' (``(Z, Y, X, 3)`` each, or None), which a look's
        texture follows as in the final render."""
        if not styles and look is None:
            raise ValueError("The preview needs at least one style picture (--styles) or a look (--look).")
        self.pipeline = pipeline
        self.stylizer = pipeline.stylizer
        self.frames = frames
        # The first frame that holds medium: what a sequence's strength and colour match are fitted on.
        self.first = holding_frames(frames)[0]
        self._motion = pipeline.frames(frames, velocities).motion if velocities is not None else None
        self.styles = list(styles)
        self.look = look
        self.res = int(res)
        self.density_scale = look.density_scale if look is not None else pipeline.density_scale
        self.camera_distance = pipeline.camera_distance
        self.radiance = pipeline.radiance
        self.timings: dict[str, float] = {}
        self.stylized = 0  # how many albedos were computed (not found in the cache)
        self._prepared: OrderedDict = OrderedDict()
        self._albedos: OrderedDict = OrderedDict()
        self._kernels: dict = {}
        self._full: dict = {}
        self._matches: dict = {}
        self._looks: OrderedDict = OrderedDict()  # the fitted look of each style (None: its fit failed)
        self._sequence = None  # the frames as the pipeline's Frames, made at the first fit (_fitted_frames)

    def initial_controls(self) -> Controls:
        """What the page starts on: the look where there is one, the first frame that holds medium."""
        camera = Camera(distance=self.camera_distance).clamped()
        return Controls(frame=self.first, look=self.look is not None, camera=camera)

    def checked(self, controls: Controls) -> Controls:
        """``controls`` with indices and values in range (a stale client cannot point past the lists)."""
        last = len(self.styles) - 1
        style = int(np.clip(controls.style, 0, max(last, 0)))
        mix_with = controls.mix_with
        if mix_with is not None and not 0 <= mix_with <= last:
            mix_with = None
        return replace(
            controls,
            style=style,
            mix_with=mix_with,
            mix=float(np.clip(controls.mix, 0.0, 1.0)),
            strength=float(np.clip(controls.strength, 0.0, 1.0)),
            frame=int(np.clip(controls.frame, 0, len(self.frames) - 1)),
            look=bool(controls.look and self.look is not None),
            camera=controls.camera.clamped(),
        )

    # ------------------------------------------------------------------ albedo
    def _style(self, controls: Controls):
        """The controls' style (``mistyle.style.Style``): the chosen picture, or its mix with the second."""
        from ..style import Style

        first = self.styles[controls.style]
        key = controls.style_key
        if key[1] is None:
            return Style((first.image,), (1.0,), (first.name,))
        second = self.styles[key[1]]
        return Style((first.image, second.image), mix_weights(key[2]), (first.name, second.name))

    def _kernels_for(self, controls: Controls):
        """The kernels at the controls' strength; the full-strength kernels and their neutral (what the
        strength fades towards) are kept per style, so a slider step runs the network once."""
        key = controls.style_key
        if key not in self._kernels:
            style = key[:3]
            if style not in self._full:
                full = self.stylizer.kernels(self._style(controls))
                self._full[style] = (full, self.stylizer.neutral(full, self.frames[self.first]))
            full, neutral = self._full[style]
            self._kernels[key] = self.stylizer.weakened(full, self.frames[self.first], controls.strength, neutral)
        return self._kernels[key]

    def _match_for(self, controls: Controls):
        """The colour match of the style (fitted on the first frame that holds medium, shared by every frame, as
        a sequence's)."""
        from ..colour_match import InvisibleMedium, fit_colour_match

        key = controls.style_key
        if key not in self._matches:
            target = self._style(controls).target
            first = self.frames[self.first]
            try:
                self._matches[key] = fit_colour_match(
                    self.stylizer.network_albedo(first, self._kernels_for(controls)),
                    first,
                    target,
                    density_scale=self.density_scale,
                    radiance=self.radiance,
                    camera_distance=self.camera_distance,
                )
            except InvisibleMedium:
                self._matches[key] = None
        return self._matches[key]

    def albedo(self, controls: Controls) -> np.ndarray:
        """The albedo ``(Z, Y, X, 3)`` of ``controls``' frame: a look's (``shown_look``), or the network's with
        the colour match at the strength (what ``mistyle-render --refine 0`` makes)."""
        look = self.shown_look(controls)
        key = (controls.style_key, look is not None, controls.frame)
        if key in self._albedos:
            self._albedos.move_to_end(key)
            return self._albedos[key]
        started = time.perf_counter()
        grid = self.frames[controls.frame]
        if not holds_medium(grid):  # before a simulation's emitter starts: rendered as it is
            albedo = empty_frame_albedo(grid.shape)
        elif look is not None:
            albedo = look.apply(grid, None if self._motion is None else self._motion.phases(controls.frame))
        else:
            albedo = self.stylizer.network_albedo(grid, self._kernels_for(controls))
            match = self._match_for(controls) if controls.strength > 0 else None
            if match is not None:
                albedo = match.apply(albedo, grid, controls.strength)
        self.timings["stylize_seconds"] = time.perf_counter() - started
        self.stylized += 1
        self._albedos[key] = albedo
        while len(self._albedos) > 8:
            self._albedos.popitem(last=False)
        return albedo

    # ------------------------------------------------------------------ looks
    def fits_look(self, controls: Controls) -> bool:
        """Whether *Render final output* of ``controls`` fits a look (the default output at full strength,
        ``PipelineSettings.fits_look``), and this session has not failed to fit it."""
        if controls.look or controls.strength < 1.0 or not self.pipeline.fits_look():
            return False
        key = controls.style_key[:3]
        return key not in self._looks or self._looks[key] is not None

    def shown_look(self, controls: Controls):
        """The look ``albedo`` applies for ``controls``: the session's loaded look where they ask for it,
        the look fitted for their style once ``fit_look`` has fitted it, else None (the network)."""
        if controls.look:
            return self.look
        return self._looks.get(controls.style_key[:3]) if self.fits_look(controls) else None

    def fit_look(self, controls: Controls, progress=None, notes: list | None = None):
        """Fit the look *Render final output* fits for ``controls``' style (``Pipeline.default_look`` on every
        frame, with the page's render settings) and keep it for that style; ``progress(step, steps,
        loss)`` after each step (what it raises ends the fit, and nothing is kept). A fit that fails is
        remembered, and the style then shows the network."""
        key = controls.style_key[:3]
        if key in self._looks:
            return self._looks[key]
        started = time.perf_counter()
        try:
            look = self.pipeline.default_look(
                self._fitted_frames(), self._style(controls), notes=notes, progress=progress
            )
        except ValueError:
            self._looks[key] = None
            raise
        self.timings["look_fit_seconds"] = time.perf_counter() - started
        self._looks[key] = look
        while len(self._looks) > MAX_FITTED_LOOKS:
            self._looks.popitem(last=False)
        return look

    def _fitted_frames(self):
        """The frames as the pipeline's ``Frames``, made once: every style's fit shares its key frames'
        preparation for the fast layer (their Ls grids), as the frames of one render do."""
        if self._sequence is None:
            self._sequence = self.pipeline.frames(np.stack(self.frames) if len(self.frames) > 1 else self.frames[0])
        return self._sequence

    # ------------------------------------------------------------------ images
    def _prepared_density(self, frame: int):
        from ..integrators import prepare_density

        if frame not in self._prepared:
            self._prepared[frame] = prepare_density(self.frames[frame], self.density_scale)
            while len(self._prepared) > 4:
                self._prepared.popitem(last=False)
        self._prepared.move_to_end(frame)
        return self._prepared[frame]

    def layer_image(self, controls: Controls) -> np.ndarray:
        """The fast layer's linear ``(res, res, 3)`` image of ``controls`` (single scattering, Ls on a grid)."""
        import torch

        from ..bridge_torch import render_views

        albedo = torch.from_numpy(np.ascontiguousarray(self.albedo(controls).transpose(3, 0, 1, 2)))
        started = time.perf_counter()
        with torch.no_grad():
            image = render_views(
                albedo,
                self._prepared_density(controls.frame),
                [controls.camera.view()],
                self.res,
                steps=LAYER_STEPS,
                radiance=self.radiance,
            )[0]
        self.timings["layer_seconds"] = time.perf_counter() - started
        return image.permute(1, 2, 0).numpy()

    def path_traced_passes(self, controls: Controls, max_spp: int = MAX_PATH_SPP):
        """Progressive path-traced images of ``controls`` (full multiple scattering, Mitsuba's volpath):
        yields ``(image, spp)``, the running mean after each pass of ``PASS_SPP`` samples."""
        from ..backend import use_variant
        from ..scenes import LightSpec, pathtraced_scene
        from ..scenes.bricks import DEFAULT_BRICK

        mi = use_variant("cpu")
        scene = mi.load_dict(
            pathtraced_scene(
                self.frames[controls.frame],
                self.albedo(controls),
                [controls.camera.view()],
                res=self.res,
                density_scale=self.density_scale,
                spp=PASS_SPP,
                light=LightSpec.parse(f"constant:{self.radiance}"),  # the fast layer's light
                bricks=DEFAULT_BRICK,
            )
        )
        total = np.zeros((self.res, self.res, 3), np.float64)
        for number in range(max_spp // PASS_SPP):
            total += np.array(mi.render(scene, sensor=0, spp=PASS_SPP, seed=number), dtype=np.float64)
            yield (total / (number + 1)).astype(np.float32), (number + 1) * PASS_SPP

    # ------------------------------------------------------------------ outputs
    def style_request(self, controls: Controls, style_paths: list[Path]) -> dict:
        """The style of ``controls`` as a ``job.RenderRequest`` takes it (``style_paths``: each style's file):
        ``{"style": (path,)}``, or ``{"mix": ("PATH:WEIGHT", ...)}``."""
        key = controls.style_key
        if key[1] is None:
            return {"style": (style_paths[controls.style],)}
        # repr: the weights parse back to the very floats the preview's look was fitted with
        first, second = mix_weights(key[2])
        return {"mix": (f"{style_paths[controls.style]}:{first!r}", f"{style_paths[key[1]]}:{second!r}")}
