"""One output of ``mistyle-render``: stylize, path trace and write its files, its report and its sheet, and
merge a chunk of a sequence into its folder.

The command line (``mistyle.render_final``) turns options into ``PipelineSettings`` and an ``OutputSpec``
and loads each output's inputs into a ``Job``; this module makes the files from a ``Job`` (``render_job``,
``write_output``, ``render_look_chunk``), so that a farm's workers write outputs as the command does.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

SETTING_OPTIONS = {
    "res": "--res",
    "spp": "--spp",
    "denoise": "--denoise",
    "max_depth": "--max-depth",
    "light": "--light",
    "coat_ior": "--coat",
    "view": "--view",
    "turntable": "--turntable",
    "strength": "--strength",
    "scale_structures": "--scale-structures",
    "colour_match": "--no-colour-match",
}
"""The options that decide how an output's frames look, as ``report.json`` records them: chunks merged
into one folder, and outputs kept by ``--resume``, must agree on all of them."""


@dataclass(frozen=True)
class OutputSpec:
    """How an output's inputs are read and its files written, beyond what ``PipelineSettings`` decide."""

    grid: str | None = None  # the grid read from .vdb densities (None: 'density', or the only one)
    up: str | None = None  # the up axis of the densities (None: what a .vdb file records, else y)
    mesh_res: int = 64  # voxels along a mesh's longest side
    fps: int = 12  # the videos' frame rate
    vdb: bool = False  # also write volume.vdb for densities that are not .vdb files


def settings_record(settings) -> dict:
    """The ``SETTING_OPTIONS`` of ``settings`` (``pipeline.PipelineSettings``) as ``report.json`` records them
    (tuples become lists)."""
    render = settings.render
    record = {
        "res": render.res,
        "spp": render.spp,
        "denoise": render.denoise,
        "max_depth": render.max_depth,
        "light": render.light,
        "coat_ior": render.coat_ior,
        "view": render.view,
        "turntable": render.turntable,
        "strength": settings.strength,
        "scale_structures": settings.scale_structures,
        "colour_match": settings.colour_match,
    }
    assert record.keys() == SETTING_OPTIONS.keys()
    return json.loads(json.dumps(record))


def log(message: str) -> None:
    from .progress import status

    status(message)


@dataclass
class Job:
    """One output's inputs, loaded and checked before any heavy work (``load_job``), and where it goes."""

    spec: OutputSpec
    output: object  # outputs.Output: the (density, style) pair and its folder
    pipeline: object  # pipeline.Pipeline
    style: object  # style.Style: the output's style, loaded once
    frames: object  # pipeline.Frames
    names: list[str]
    views: list  # scenes.View
    coat_mesh: tuple | None = None  # (vertices, faces) placed in the medium box, for --mesh with --coat
    coat_mesh_path: Path | None = None
    transforms: list | None = None  # per frame, the vdb.VdbTransform of a .vdb density
    sources: list | None = None  # per frame, the .vdb file it was read from (its other grids travel into volume.vdb)
    up: str = "y"  # the world up axis volume.vdb is written in (conventions.UP_AXES)
    notes: list[str] = field(default_factory=list)
    out: Path | None = None  # the staging folder of the run (``ownership.staged_directory``), set in ``run``
    first: int = 0  # the index of the first frame in the whole sequence (``--frames``)
    total_frames: int = 1  # the whole sequence's frames
    look: object = None  # look.Look: stylize with it instead of the style
    merged: bool = False  # the output merges frame by frame into its folder (``ownership.chunk_staging``)
    report: dict = field(default_factory=dict)

    @property
    def sequence(self) -> bool:
        return self.frames.sequence or self.merged


def load_job(spec: OutputSpec, output, pipeline, styles: dict, frame_range: tuple[int, int] | None = None) -> Job:
    """Check and load one output's inputs (``output``: an ``outputs.Output``; ``styles``: path -> (decoded
    image, conversion notes); ``frame_range``: the 0-based, inclusive frames of a chunk); nothing heavy
    runs before this returns."""
    from .files import density_frame_files, load_density_frames
    from .style import Style

    notes = [note for path, _ in output.style.parts for note in styles[path][1]]
    style = Style(
        tuple(styles[path][0] for path, _ in output.style.parts),
        tuple(weight for _, weight in output.style.parts),
        tuple(Path(path).name for path, _ in output.style.parts),
    )
    pipeline.light()  # a bad --light fails here, before the density is read
    coat_mesh, transforms, sources, up = None, None, None, spec.up or "y"
    if output.density.mesh:
        from .data.mesh import fit_to_box, load_mesh, voxelize

        vertices, faces = load_mesh(output.density.path)
        densities, velocities, names = (
            [voxelize(vertices, faces, spec.mesh_res, supersample=2)],
            None,
            [output.density.name],
        )
        if pipeline.settings.render.coat_ior is not None:
            placed, _ = fit_to_box(np.asarray(vertices, np.float64), spec.mesh_res, 0.05)
            coat_mesh = (placed, faces)
    else:
        # notes: a VDB sequence's velocity units and frame rate as assumed, frames without a velocity
        loaded = load_density_frames(output.density.path, grid=spec.grid, up=spec.up, notes=notes)
        densities, velocities, names, transforms = loaded.densities, loaded.velocities, loaded.names, loaded.transforms
        up = loaded.up or up
        if transforms is not None:
            sources = density_frame_files(output.density.path)
    total, first, motion = len(densities), 0, None
    if frame_range is not None:
        first, last = frame_range
        if last >= total:
            raise ValueError(f"--frames {first}-{last} lies outside {output.density.path}'s frames 0-{total - 1}.")
        chosen = slice(first, last + 1)
        if velocities is not None:
            from .advection import TextureMotion, first_needed

            # The look's texture follows the velocities from before the chunk too, as it does through
            # the whole sequence, so that the chunks' frames are the whole sequence's.
            begin = first_needed(first)
            motion = TextureMotion(velocities[begin : last + 1], begin=begin)
        densities, names = densities[chosen], names[chosen]
        velocities = None if velocities is None else velocities[chosen]
        transforms = None if transforms is None else transforms[chosen]
        sources = None if sources is None else sources[chosen]
    frames = pipeline.frames(densities, velocities, names, motion, first)
    return Job(
        spec=spec,
        output=output,
        pipeline=pipeline,
        style=style,
        frames=frames,
        names=names,
        views=pipeline.views(),
        coat_mesh=coat_mesh,
        transforms=transforms,
        sources=sources,
        up=up,
        notes=notes,
        first=first,
        total_frames=total,
    )


def write_output(job: Job) -> None:
    """Make ``job``'s output: in a staging folder that replaces its folder only when complete, or, for a
    chunk of a sequence (``job.merged``), in a staging folder whose files then merge into the folder."""
    from .ownership import chunk_staging, output_lock, staged_directory

    if job.merged:
        check_mergeable(job)
        with chunk_staging(job.output.folder) as staging:
            job.out = staging
            render_job(job)
            with output_lock(job.output.folder, wait=True) as (folder, _):
                merge_chunk(job, folder)
    else:
        with staged_directory(job.output.folder) as staging:
            job.out = staging
            render_job(job)


def render_look_chunk(pipeline, spec: OutputSpec, density, look_path, out, frame_range: tuple[int, int]) -> None:
    """Frames ``frame_range`` (0-based, inclusive) of the sequence ``density`` stylized from the look file
    ``look_path`` and merged into ``out``: what ``mistyle-render --look L --frames A-B`` does, for a farm's
    worker that keeps ``pipeline`` (its network loaded) from one chunk to the next."""
    from .look import Look
    from .outputs import plan_outputs

    if spec.vdb or Path(density).suffix.lower() == ".vdb":
        from .files.vdb import vdb_interpreter

        vdb_interpreter()  # no OpenVDB binding: say so before any work
    look = Look.load(look_path, stylizer=pipeline.stylizer)
    (output,) = plan_outputs([density], None, [look_path], None, out, True, False)
    styles = {output.style.parts[0][0]: (look.style, [])}
    job = load_job(spec, output, pipeline, styles, frame_range)
    job.look, job.merged = look, True
    write_output(job)


def render_job(job: Job) -> None:
    """Stylize, path trace and write one output into ``job.out``."""
    report = job.report = {"inputs": _inputs_record(job), "notes": job.notes}
    write_coat_mesh(job)
    stylized = stylize_frames(job, report)
    images, layer_images = render_frames(job, stylized, report)
    started = time.perf_counter()
    report["files"] = write_assets(job, stylized)
    report["assets_seconds"] = time.perf_counter() - started
    write_report(job, stylized, images, layer_images, report)


def write_batch_index(out: Path, pipeline) -> None:
    """``out/index.html`` for the complete outputs on disk, titled with their number."""
    from .outputs import BATCH_KIND, batch_entries, batch_renders
    from .ownership import writing
    from .pages import INDEX_FILE, write_index

    count = len(batch_renders(out))
    if count:
        with writing(out, BATCH_KIND, [INDEX_FILE], also_ours=batch_entries(Path(out))):
            write_index(
                out, f"mistyle: {count} render{'s' if count != 1 else ''}", [f"checkpoint {pipeline.stylizer.path}"]
            )


def write_coat_mesh(job: Job) -> None:
    """The coat of ``--mesh ... --coat``, placed in the medium box, as the path tracer reads it."""
    from .data.mesh import write_ply

    if job.coat_mesh is not None:
        job.coat_mesh_path = write_ply(job.out / "coat_mesh.ply", *job.coat_mesh)


def check_same_settings(record: dict, folder: Path, why: str, other_fix: str = "") -> None:
    """``ValueError`` naming the first option whose value in ``record`` (``settings_record``) differs from the
    one ``folder``'s render used."""
    from .outputs import REPORT_FILE

    try:
        held = json.loads((folder / REPORT_FILE).read_text()).get("inputs", {})
    except (OSError, ValueError, AttributeError):
        raise ValueError(
            f"{folder / REPORT_FILE} cannot be read, so the render settings of {folder} are unknown; "
            f"{other_fix or 'remove that folder'}, or choose another --out."
        ) from None
    for key, value in record.items():
        if key in held and held[key] != value:
            option, fixes = SETTING_OPTIONS[key], ", ".join(filter(None, [other_fix, "or choose another --out"]))
            raise ValueError(
                f"{folder} was rendered with {option} {held[key]} and this run asks for {value}; {why} only with the "
                f"same settings: give {option} {held[key]}, {fixes}."
            )


def _inputs_record(job: Job) -> dict:
    spec, pipeline = job.spec, job.pipeline
    refinement = pipeline.look_refinement() if job.look is not None else pipeline.refinement(len(job.frames.densities))
    return {
        "density": str(job.output.density.path),
        "mesh": job.output.density.mesh,
        "grid": spec.grid,
        "style": job.look.meta.get("style", "a look") if job.look is not None else job.output.style.describe(),
        "frames": len(job.frames.densities),
        "shape_zyx": list(job.frames.densities[0].shape),
        "checkpoint": str(pipeline.stylizer.path),
        "look_sha256": None if job.look is None else job.look.meta.get("file_sha256"),
        **settings_record(pipeline.settings),
        "density_scale": pipeline.density_scale,
        "refine_steps": refinement.layer_steps,
        "refine_path_steps": refinement.path_steps,
        "views": len(job.views),
    }


def _frame_suffix(job: Job, index: int) -> str:
    """How a frame's files are told apart: ``_frameNNNN`` in a sequence, nothing for one frame."""
    return f"_frame{job.first + index:04d}" if job.sequence else ""


# ---------------------------------------------------------------------------- stage 2: stylize and refine
def stylize_frames(job: Job, report: dict):
    """The pipeline's albedos for every frame (``pipeline.Stylization``); the feed-forward albedo is
    written as ``albedo*.npy`` (the grids by ``write_assets``)."""
    from .files import write_npy

    if job.look is not None:
        stylized = job.pipeline.look_stylization(job.frames, job.look, notes=job.notes)
    else:
        stylized = job.pipeline.stylize(job.frames, job.style, notes=job.notes)
    report.update(stylized.report)
    for index, albedo in enumerate(stylized.network):
        write_npy(job.out / f"albedo{_frame_suffix(job, index)}.npy", albedo)
    return stylized


# ---------------------------------------------------------------------------- stage 3: path trace
def render_frames(job: Job, stylized, report: dict):
    """Path-trace the pipeline's albedos and write EXR/PNG (and video); also the layer's images of
    the feed-forward albedos. Returns ``(images, layer_images)``, linear ``(H, W, 3)`` each."""
    from .files import write_exr, write_gif, write_mp4, write_png
    from .progress import bar
    from .tone import display

    spec, pipeline = job.spec, job.pipeline
    plan = pipeline.render_plan(job.frames, job.views, job.first)
    total = sum(len(views) for _, views in plan)
    started = time.perf_counter()
    with bar(total, "path tracing", unit="image") as progress_bar:
        images, render_seconds = pipeline.path_trace(
            job.frames,
            stylized.albedos,
            job.views,
            coat_mesh=job.coat_mesh_path,
            progress=lambda done, count, seconds: progress_bar.update(1),
            first=job.first,
            notes=job.notes,  # images of a sequence or turntable that show no medium, and why
            chunk=job.merged,  # frames merged into a folder: others, rendered apart, may show the medium
        )
    layer_images = [
        image
        for frame, views in plan
        for image in pipeline.layer_images(job.frames, frame, stylized.network[frame], views)
    ]
    report["render_seconds"] = time.perf_counter() - started
    render = pipeline.settings.render
    log(f"path traced {total} image(s) of {render.res}^2 at {render.spp} spp in {report['render_seconds']:.1f} s")
    report["render_seconds_per_image"] = float(np.mean(render_seconds))

    kind = "sequence" if job.sequence else "turntable" if render.turntable else "view"
    for index, image in enumerate(images):
        stem = f"{kind}_{job.first + index:04d}" if len(images) > 1 or job.merged else "final"
        write_exr(job.out / f"{stem}.exr", image)
        write_png(job.out / f"{stem}.png", display(image), srgb=False)
        write_png(job.out / f"{stem}_network_layer.png", display(layer_images[index]), srgb=False)
    if len(images) > 1 and not job.merged:  # a merged folder's video is made of all its frames (merge_chunk)
        frames = [(display(image) * 255 + 0.5).astype(np.uint8) for image in images]
        report["video"] = [
            write_mp4(job.out / f"{kind}.mp4", frames, spec.fps).name,
            write_gif(job.out / f"{kind}.gif", frames, spec.fps).name,
        ]
    return images, layer_images


# ---------------------------------------------------------------------------- stage 4: assets
def write_assets(job: Job, stylized) -> list[str]:
    """What a Mitsuba, Houdini or Blender user opens: per frame the density and the path-traced albedo
    (``.vol``, medium box as bounding box; also the feed-forward ``albedo.vol`` when another albedo was
    path traced), the ``scene.xml`` that reproduces the render, and ``volume.vdb`` (density + albedo
    as ``Cd``) in the input ``.vdb``'s transform, or in the medium box's with ``--vdb``; the input's own
    ``vdb.PASSENGER_GRIDS`` (temperature, flame, heat, colour) travel into it. Returns the file names
    written."""
    from .scenes.export import write_medium_grid, write_scene_files

    # scene.xml holds one medium: bricks only speed the render up (scenes.export).
    options = job.pipeline.trace_options()
    scene_options = {key: value for key, value in options.items() if key not in ("device", "bricks")}
    written, carried = [], {}
    for frame, views in job.pipeline.render_plan(job.frames, job.views, job.first):
        suffix = _frame_suffix(job, frame)
        density, albedo = job.frames.densities[frame], stylized.albedos[frame]
        if stylized.refined:
            written.append(write_medium_grid(job.out / f"albedo{suffix}.vol", stylized.network[frame]).name)
        paths = write_scene_files(
            job.out,
            density,
            albedo,
            views,
            suffix=suffix,
            coat_mesh=job.coat_mesh_path,
            albedo_name="albedo_refined" if stylized.refined else "albedo",
            **scene_options,
        )
        written += [path.name for path in paths.values()]
        if job.transforms is not None or job.spec.vdb:
            from .files.vdb import write_vdb
            from .files.vdb_frames import passenger_grids, passengers_at
            from .files.vdb_layout import ALBEDO_GRID, DENSITY_GRID, VdbTransform, mistyle_metadata

            transform = (
                job.transforms[frame]
                if job.transforms is not None
                else VdbTransform.for_medium_box(density.shape, job.up)
            )
            # The albedo only where there is medium: elsewhere it is never seen, and zeros stay inactive (small files).
            shown = albedo * (density > 0)[..., None]
            metadata = mistyle_metadata(
                transform,
                density.shape,
                density_scale=job.pipeline.density_scale,
                up=job.up,
                style=job.output.style.describe(),
                checkpoint=job.pipeline.stylizer.path.name,
            )
            grids = {DENSITY_GRID: density, ALBEDO_GRID: shown}
            if job.sources is not None:
                found, skipped = passenger_grids(job.sources[frame], job.spec.grid)
                grids.update(passengers_at(found, transform, density.shape))
                for name in found:
                    carried[name] = carried.get(name, 0) + 1
                for name, reason in skipped.items():
                    job.notes.append(f"{job.sources[frame].name}: grid '{name}' not carried into volume.vdb ({reason})")
            path = write_vdb(
                job.out / f"volume{suffix}.vdb", transform, grids, metadata=metadata, grid_metadata=metadata
            )
            written.append(path.name)
    if carried:
        volumes = sum(name.startswith("volume") for name in written)
        shown = [f"'{name}'" + ("" if n == volumes else f" ({n} of {volumes} frames)") for name, n in carried.items()]
        job.notes.append(
            f"{'the volume VDBs carry' if volumes > 1 else 'volume.vdb carries'} the input's "
            f"{', '.join(shown)} grid(s) as read (not stylized), for the artist's shaders"
        )
    return written


# ---------------------------------------------------------------------------- stage 5: report
METRIC_KEYS = ("rgb_swd", "patch_swd", "hue_coverage", "structure", "swd_final", "hist_final", "swd_layer")
SHEET_LABELS = ("style", "the network (fast layer)", "the output (path traced)")
"""``sheet.png``'s panels, whole runs and merged chunks alike: the style, what the network alone gives, and
what was path traced (the default output: a look fitted on the frames)."""


def write_report(job: Job, stylized, images, layer_images, report: dict) -> None:
    """Style metrics of every image against the style, ``report.json``, ``sheet.png`` and a summary line;
    a chunk merged into a sequence's folder (``job.merged``) measures each frame alone, which is all
    ``merge_chunk`` keeps, and leaves the folder's files to it.

    A metric that cannot be computed is ``null`` in the report, with a note, also shown on the console:
    the style metrics of images that see no medium (the pipeline refuses a render where none does, and
    names why each image does not: ``Pipeline.check_images``), ``patch_swd`` when no 5x5 patch lies inside it."""
    from .files import atomic_write_bytes
    from .objective.metrics import foreground_mask, style_distance, style_fidelity
    from .outputs import REPORT_FILE
    from .pages import SHEET_FILE, write_sheet
    from .tone import display

    style = stylized.target
    started = time.perf_counter()
    visible = [image for image in images if foreground_mask(image).any()]
    if visible and len(visible) < len(images):
        unseen = len(images) - len(visible)
        note = f"{unseen} of {len(images)} image(s) see no medium; the style metrics are of the others"
        job.notes.append(note)
        log(f"note: {note}")
    if not visible:
        note = "no pixel of the final render sees the medium; the style metrics are left out"
        job.notes.append(note)
        log(f"note: {note}")
    if job.merged:  # the folder's report, sheet and index give each frame's metrics alone: merge_chunk
        report["frames"] = {
            f"{job.first + index:04d}": frame_metrics(image, style) for index, image in enumerate(images)
        }
        report["metrics_seconds"] = time.perf_counter() - started
        return
    if visible:
        final = [style_distance(image, style) for image in visible]
        report["swd_final"] = float(np.mean([distance["swd"] for distance in final]))
        report["hist_final"] = float(np.mean([distance["hist"] for distance in final]))
        seen = [image for image in layer_images if foreground_mask(image).any()]
        report["swd_layer"] = float(np.mean([style_distance(image, style)["swd"] for image in seen])) if seen else None
        report.update(style_fidelity(visible, style))
    else:
        report.update(dict.fromkeys(METRIC_KEYS))
    for key in METRIC_KEYS:
        if report.get(key) is not None and not np.isfinite(report[key]):
            report[key] = None
            job.notes.append(f"{key} left out: too few pixels see the medium to measure it")
    report["metrics_seconds"] = time.perf_counter() - started
    atomic_write_bytes(job.out / REPORT_FILE, (json.dumps(report, indent=1) + "\n").encode())
    seconds = sum(
        report.get(key, 0.0) for key in ("stylize_seconds", "look_seconds", "refine_seconds", "render_seconds")
    )

    def shown(key, digits):
        return "-" if report[key] is None else f"{report[key]:.{digits}f}"

    refinement, settings = stylized.refinement, job.pipeline.settings
    if stylized.look is not None:
        key_frames = ",".join(map(str, stylized.look.meta["key_frames"]))
        stage = f"a look fitted on key frames {key_frames}" if job.sequence else "a look fitted on the frame"
    else:
        stage = f"refine {refinement.layer_steps}+{refinement.path_steps} steps"
    lines = [
        f"{job.output.density.path.name} x {job.output.style.describe(names_only=True)}"[:110],
        f"RGB SWD {shown('rgb_swd', 4)}   patch SWD {shown('patch_swd', 4)}   hue coverage {shown('hue_coverage', 2)}",
        f"strength {settings.strength:g}, {stage}, {settings.render.res}^2 x {settings.render.spp} spp, "
        f"{seconds:.1f} s",
    ]
    write_sheet(
        job.out / SHEET_FILE,
        list(zip(SHEET_LABELS, (style, display(layer_images[0]), display(images[0])))),
        lines,
    )
    keys = (
        "stylize_seconds",
        "look_seconds",
        "refine_seconds",
        "render_seconds",
        "rgb_swd",
        "patch_swd",
        "hue_coverage",
    )
    print(json.dumps({key: report[key] for key in keys if key in report}))


def check_mergeable(job: Job) -> None:
    """``ValueError`` when ``job``'s folder holds frames of another sequence or look: chunks merge only
    with chunks of the same density and look (or style)."""
    from .outputs import REPORT_FILE, is_mistyle_output

    folder = job.output.folder
    if not is_mistyle_output(folder) or not (folder / REPORT_FILE).is_file():
        return
    held = json.loads((folder / REPORT_FILE).read_text()).get("inputs", {})
    ours = _inputs_record(job)
    for record in (held, ours):  # the same folder of frames, however the command named it
        record["density"] = str(Path(record.get("density", "")).resolve())
    for key, what in (("density", "density"), ("look_sha256", "look"), ("style", "style"), ("shape_zyx", "grid size")):
        if held.get(key) != ours.get(key):
            raise ValueError(
                f"{folder} holds frames of another {what} ({held.get(key)}); chunks merge only with chunks of the "
                "same density and look. Choose another --out, or remove that folder first."
            )
    check_same_settings(settings_record(job.pipeline.settings), folder, "a chunk merges into it")


def frame_metrics(image: np.ndarray, style: np.ndarray) -> dict:
    """One frame's style metrics (``objective.metrics.style_fidelity``), None where they cannot be measured."""
    from .objective.metrics import foreground_mask, style_fidelity

    if not foreground_mask(image).any():
        return dict.fromkeys(FRAME_METRICS)
    metrics = style_fidelity([image], style)
    return {key: (float(value) if value is not None and np.isfinite(value) else None) for key, value in metrics.items()}


FRAME_METRICS = ("rgb_swd", "patch_swd", "hue_coverage", "structure")


def merge_chunk(job: Job, folder: Path) -> None:
    """Move a chunk's files from ``job.out`` into ``folder`` (``ownership.merge_files``), then write the folder's
    ``report.json`` (every frame present, each with its metrics; the chunks that made them), its video,
    ``sheet.png`` (its first frame) and ``index.html``. Two chunks give the files one run gives.
    The folder's manifest takes the files in, so a later chunk or ``--overwrite`` knows them for mistyle's."""
    from .outputs import REPORT_FILE
    from .ownership import writing
    from .pages import INDEX_FILE, SHEET_FILE

    names = [p.name for p in job.out.iterdir() if p.is_file()]
    with writing(folder, "sequence", names + [REPORT_FILE, "sequence.mp4", "sequence.gif", SHEET_FILE, INDEX_FILE]):
        _merge_chunk_files(job, folder)


def _merge_chunk_files(job: Job, folder: Path) -> None:
    from .files import atomic_write_bytes, read_png, write_gif, write_mp4
    from .outputs import REPORT_FILE
    from .ownership import merge_files
    from .pages import SHEET_FILE, write_index, write_sheet

    chunk, render = job.report, job.pipeline.settings.render
    merge_files(job.out, folder)
    old = json.loads((folder / REPORT_FILE).read_text()) if (folder / REPORT_FILE).is_file() else {}
    frames = {**old.get("frames", {}), **chunk["frames"]}
    frames = dict(sorted(frames.items()))
    done = set(chunk["frames"])
    timings = {key: chunk[key] for key in ("stylize_seconds", "refine_seconds", "render_seconds") if key in chunk}
    this = {"frames": [job.first, job.first + len(job.frames.densities) - 1], **timings}
    for key in ("temporal_flicker", "temporal_flicker_unwarped"):
        if key in chunk:
            this[key] = chunk[key]
    chunks = [
        c
        for c in old.get("chunks", [])
        if not set(f"{i:04d}" for i in range(c["frames"][0], c["frames"][1] + 1)) <= done
    ]
    report = {
        "inputs": {**chunk["inputs"], "frames": len(frames), "frames_in_sequence": job.total_frames},
        "notes": list(dict.fromkeys(old.get("notes", []) + job.notes)),
        "frames": frames,
        "chunks": sorted(chunks + [this], key=lambda c: c["frames"][0]),
    }
    for key in FRAME_METRICS:
        values = [entry[key] for entry in frames.values() if entry.get(key) is not None]
        report[key] = float(np.mean(values)) if values else None
    stems = [f"sequence_{index}" for index in frames]
    shown = [read_png(folder / f"{stem}.png") for stem in stems if (folder / f"{stem}.png").is_file()]
    if len(shown) > 1:
        report["video"] = [
            write_mp4(folder / "sequence.mp4", shown, job.spec.fps).name,
            write_gif(folder / "sequence.gif", shown, job.spec.fps).name,
        ]
    first = stems[0]
    style = job.look.style if job.look is not None else job.style.images[0]
    # The look's own record of its style, not its file's name: a farm's workers hold it under another.
    described = (
        job.look.meta.get("style", "a look") if job.look is not None else job.output.style.describe(names_only=True)
    )
    lines = [
        f"{job.output.density.path.name} x {described}"[:110],
        f"{len(frames)} of {job.total_frames} frames; mean RGB SWD {_shown(report, 'rgb_swd', 4)}, "
        f"patch SWD {_shown(report, 'patch_swd', 4)}, hue coverage {_shown(report, 'hue_coverage', 2)}",
        f"first frame {frames and next(iter(frames))} shown; {render.res}^2 x {render.spp} spp",
    ]
    write_sheet(
        folder / SHEET_FILE,
        list(
            zip(
                SHEET_LABELS,
                (
                    style,
                    read_png(folder / f"{first}_network_layer.png") / 255.0,
                    read_png(folder / f"{first}.png") / 255.0,
                ),
            )
        ),
        lines,
    )
    atomic_write_bytes(folder / REPORT_FILE, (json.dumps(report, indent=1) + "\n").encode())  # the index lists it
    write_index(
        folder,
        f"mistyle: {len(frames)} frame{'s' if len(frames) != 1 else ''} of {job.output.density.name}",
        [
            f"frame {index}: RGB SWD {_shown(entry, 'rgb_swd', 4)}, patch SWD {_shown(entry, 'patch_swd', 4)}, "
            f"hue coverage {_shown(entry, 'hue_coverage', 2)}"
            for index, entry in frames.items()
        ],
    )
    report["files"] = sorted(p.name for p in folder.iterdir() if p.is_file() and not p.name.startswith("."))
    atomic_write_bytes(folder / REPORT_FILE, (json.dumps(report, indent=1) + "\n").encode())
    print(json.dumps({"frames": this["frames"], **{key: report[key] for key in FRAME_METRICS}}))


def _shown(record: dict, key: str, digits: int) -> str:
    return "-" if record.get(key) is None else f"{record[key]:.{digits}f}"
