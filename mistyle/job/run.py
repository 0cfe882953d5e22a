"""One output's inputs loaded and checked (``Job``, ``load_job``), stylized, path traced and written:
its images, videos and grids (``render_job``, ``write_output``, ``render_look_chunk``)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .report import check_mergeable, inputs_record, merge_chunk, write_report
from .spec import Job, OutputSpec, log


def load_job(spec: OutputSpec, output, pipeline, styles: dict, frame_range: tuple[int, int] | None = None) -> Job:
    """Check and load one output's inputs (``output``: an ``outputs.Output``; ``styles``: path -> (decoded
    image, conversion notes); ``frame_range``: the 0-based, inclusive frames of a chunk); nothing heavy
    runs before this returns."""
    from ..files import density_frame_files, load_density_frames
    from ..style import Style

    notes = [note for path, _ in output.style.parts for note in styles[path][1]]
    style = Style(
        tuple(styles[path][0] for path, _ in output.style.parts),
        tuple(weight for _, weight in output.style.parts),
        tuple(Path(path).name for path, _ in output.style.parts),
    )
    pipeline.light()  # a bad --light fails here, before the density is read
    coat_mesh, transforms, sources, up = None, None, None, spec.up or "y"
    if output.density.mesh:
        from ..data.mesh import fit_to_box, load_mesh, voxelize

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
            from ..advection import TextureMotion, first_needed

            # The look's texture follows the velocities from before the chunk too, as it does through
            # the whole sequence, so that the chunks' frames are the whole sequence's.
            begin = first_needed(first)
            motion = TextureMotion(velocities[begin : last + 1], begin=begin)
        densities, names = densities[chosen], names[chosen]
        velocities = None if velocities is None else velocities[chosen]
        transforms = None if transforms is None else transforms[chosen]
        sources = None if sources is None else sources[chosen]
    frames = pipeline.frames(densities, velocities, names, motion, first, chunk=frame_range is not None)
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


def write_output(job: Job, replace: bool = True) -> None:
    """Make ``job``'s output: in a staging folder that replaces its folder only when complete (a
    complete render already there only with ``replace``, ``--overwrite``), or, for a chunk of a
    sequence (``job.merged``), in a staging folder whose files then merge into the folder."""
    from ..outputs import RENDER_KINDS
    from ..ownership import chunk_staging, output_lock, staged_directory

    if job.merged:
        check_mergeable(job)
        with chunk_staging(job.output.folder) as staging:
            job.out = staging
            render_job(job)
            with output_lock(job.output.folder, wait=True) as (folder, _):
                merge_chunk(job, folder)
    else:
        with staged_directory(job.output.folder, keep=() if replace else RENDER_KINDS) as staging:
            job.out = staging
            render_job(job)


def render_look_chunk(pipeline, spec: OutputSpec, density, look_path, out, frame_range: tuple[int, int]) -> None:
    """Frames ``frame_range`` (0-based, inclusive) of the sequence ``density`` stylized from the look file
    ``look_path`` and merged into ``out``: what ``mistyle-render --look L --frames A-B`` does, for a farm's
    worker that keeps ``pipeline`` (its network loaded) from one chunk to the next."""
    from ..look import Look
    from ..outputs import plan_outputs

    if spec.vdb or Path(density).suffix.lower() == ".vdb":
        from ..files.vdb import vdb_interpreter

        vdb_interpreter()  # no OpenVDB binding: say so before any work
    look = Look.load(look_path, stylizer=pipeline.stylizer)
    (output,) = plan_outputs([density], None, [look_path], None, out, True, False)
    styles = {output.style.parts[0][0]: (look.style, [])}
    job = load_job(spec, output, pipeline, styles, frame_range)
    job.look, job.merged = look, True
    write_output(job)


def render_job(job: Job) -> None:
    """Stylize, path trace and write one output into ``job.out``."""
    report = job.report = {"inputs": inputs_record(job), "notes": job.notes}
    write_coat_mesh(job)
    stylized = stylize_frames(job, report)
    images, layer_images = render_frames(job, stylized, report)
    started = time.perf_counter()
    report["files"] = write_assets(job, stylized)
    report["assets_seconds"] = time.perf_counter() - started
    write_report(job, stylized, images, layer_images, report)


def write_batch_index(out: Path, pipeline) -> None:
    """``out/index.html`` for the complete outputs on disk, titled with their number."""
    from ..outputs import BATCH_KIND, batch_entries, batch_renders
    from ..ownership import writing
    from ..pages import INDEX_FILE, write_index

    count = len(batch_renders(out))
    if count:
        with writing(out, BATCH_KIND, [INDEX_FILE], also_ours=batch_entries(Path(out))):
            write_index(
                out, f"mistyle: {count} render{'s' if count != 1 else ''}", [f"checkpoint {pipeline.stylizer.path}"]
            )


def write_coat_mesh(job: Job) -> None:
    """The coat of ``--mesh ... --coat``, placed in the medium box, as the path tracer reads it."""
    from ..data.mesh import write_ply

    if job.coat_mesh is not None:
        job.coat_mesh_path = write_ply(job.out / "coat_mesh.ply", *job.coat_mesh)


def _frame_suffix(job: Job, index: int) -> str:
    """How a frame's files are told apart: ``_frameNNNN`` in a sequence, nothing for one frame."""
    return f"_frame{job.first + index:04d}" if job.sequence else ""


# ---------------------------------------------------------------------------- stage 2: stylize and refine
def stylize_frames(job: Job, report: dict):
    """The pipeline's albedos for every frame (``pipeline.Stylization``); the feed-forward albedo is
    written as ``albedo*.npy`` (the grids by ``write_assets``)."""
    from ..files import write_npy

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
    from ..files import write_exr, write_gif, write_mp4, write_png
    from ..progress import bar
    from ..tone import display

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
    from ..scenes.export import write_medium_grid, write_scene_files

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
            from ..files.vdb import write_vdb
            from ..files.vdb_frames import passenger_grids, passengers_at
            from ..files.vdb_layout import ALBEDO_GRID, DENSITY_GRID, VdbTransform, mistyle_metadata

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
