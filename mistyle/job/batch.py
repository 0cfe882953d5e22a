"""A run of outputs, as ``mistyle-render`` makes them: what to render and where (``RenderRequest``), the
outputs planned, checked and written one after another (``render_outputs``), and a look fitted and
saved on the way (``save_look``).

The command line, the preview's page and scripts call ``render_outputs`` with ``PipelineSettings``, an
``OutputSpec`` and a ``RenderRequest``; option parsing stays in ``mistyle.render_final``.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from .spec import OutputSpec, check_same_settings, log, settings_record


@dataclass(frozen=True)
class RenderRequest:
    """What a run renders and where it writes, beyond how (the settings and the ``OutputSpec``): the
    inputs and outputs of ``mistyle-render``, by their option names."""

    density: tuple = ()  # density files or folders of frames (one output each), or
    mesh: tuple = ()  # closed meshes, voxelized
    style: tuple = ()  # style images or folders of them (one output each), or
    mix: tuple = ()  # "IMAGE:WEIGHT" items of one mixed style, or
    look: Path | None = None  # a look file to stylize with instead of a style
    save_look: Path | None = None  # fit a look on the one density and write it here
    out: Path | None = None  # the output folder (None: only save_look)
    overwrite: bool = False
    resume: bool = False
    frame_range: tuple[int, int] | None = None  # a chunk of a sequence (0-based, inclusive), merged into out
    key_frames: str | None = None  # "0,40,80": the frames save_look fits on

    @property
    def sources(self) -> tuple:
        return self.density or self.mesh

    def style_parts(self) -> list[tuple[Path, float]]:
        """The style a look is fitted to: the one style image, or the mix's images and weights."""
        from ..outputs import style_choices

        (choice,) = style_choices(list(self.style) or None, list(self.mix) or None)
        return list(choice.parts)


def check_look_replaceable(path: Path, overwrite: bool) -> None:
    """``ValueError`` unless a look may be saved at ``path``: a new file, or with ``overwrite`` a look."""
    from ..look import is_look_file

    if not (path.exists() or path.is_symlink()):
        return
    if path.is_symlink():
        raise ValueError(
            f"--save-look {path} is a symbolic link (to {os.readlink(path)}); mistyle saves a look as a file of "
            "its own, never through a link: give the link's target, or another name."
        )
    if not is_look_file(path):
        raise ValueError(
            f"--save-look {path} already exists and is not a mistyle look; mistyle replaces only its own files. "
            "Choose another file name."
        )
    if not overwrite:
        raise ValueError(f"The look {path} already exists; pass --overwrite to replace it, or choose another name.")


def render_outputs(settings, spec: OutputSpec, request: RenderRequest, log: Callable[[str], None] = log) -> str:
    """Every output of ``request`` with ``settings`` (``pipeline.PipelineSettings``): planned and checked
    before any work (no user's file replaced, ``outputs.plan_outputs``), each input read and each style
    decoded once, the look loaded or fitted, then each output written (``write_output``). Returns the
    line that says what was written."""
    from ..backend import use_variant
    from ..files import load_style
    from ..outputs import is_mistyle_output, plan_outputs
    from ..ownership import check_not_in_use
    from ..pipeline import Pipeline
    from .run import load_job, write_batch_index, write_output

    if request.save_look is not None:
        check_look_replaceable(Path(request.save_look), request.overwrite)
    look_mode = request.look is not None or request.save_look is not None
    # A look's sequence, and any chunk of frames, merges frame by frame into its folder.
    merging = request.frame_range is not None or (look_mode and all(Path(p).is_dir() for p in request.sources))
    planned = []
    if request.out is not None:
        styles_given = [request.look] if request.look is not None else list(request.style) or None
        planned = plan_outputs(
            list(request.density) or None,
            list(request.mesh) or None,
            styles_given,
            list(request.mix) or None,
            request.out,
            request.overwrite or merging,
            request.resume,
        )
    keep = request.resume and not request.overwrite and not merging
    outputs = [output for output in planned if not (keep and is_mistyle_output(output.folder))]
    if not merging:  # a chunk waits for a merging one; a whole run would be refused when it writes
        for output in outputs:
            check_not_in_use(output.folder)
    for output in planned:
        if output not in outputs:
            check_same_settings(
                settings_record(settings), output.folder, "--resume keeps it", "pass --overwrite to render it again"
            )
    batch = len(planned) > 1
    if len(outputs) < len(planned):
        log(f"note: --resume: {len(planned) - len(outputs)} of {len(planned)} output(s) already complete, kept")
    for source in dict.fromkeys(request.sources):
        if not Path(source).exists():
            raise ValueError(f"{'Mesh' if request.mesh else 'Density'} {source} does not exist.")
    styles = {}
    if request.look is None:
        # Every input is looked at before the first output is made, so a bad file late in a batch
        # does not stop it half way (each density is read in full when its turn comes). Each style is
        # decoded once, with the notes on its conversion.
        images = [image for output in outputs for image, _ in output.style.parts]
        if request.save_look is not None:
            images = [path for path, _ in request.style_parts()]
        for path in dict.fromkeys(images):
            notes: list[str] = []
            styles[path] = (load_style(path, notes), notes)
            for note in notes:
                log(f"note: {note}")
    if spec.vdb or any(output.density.path.suffix.lower() == ".vdb" for output in outputs):
        from ..files.vdb import vdb_interpreter

        vdb_interpreter()  # no OpenVDB binding: say so before any work
    use_variant(settings.device)
    pipeline = Pipeline(settings, log=log)
    look = None
    if request.look is not None:
        from ..look import Look

        look = Look.load(request.look, stylizer=pipeline.stylizer)
        styles[request.look] = (look.style, [])
    elif request.save_look is not None:
        look = save_look(pipeline, spec, request, styles, log)
        if not outputs:
            return f"wrote the look {request.save_look}"
        for output in outputs:
            styles[output.style.parts[0][0]] = (look.style, [])
    try:
        for number, output in enumerate(outputs, 1):
            if batch:
                log(f"[{number}/{len(outputs)}] {output.name}")
            job = load_job(spec, output, pipeline, styles, request.frame_range)
            job.look, job.merged = look, merging
            write_output(job, replace=request.overwrite)
    finally:
        if batch:  # also when a pair failed: the index shows the outputs that are complete
            write_batch_index(request.out, pipeline)
    where = f"{request.out}/ ({len(planned)} outputs and index.html)" if batch else f"{request.out}/"
    looked = f"the look {request.save_look}, and " if request.save_look is not None else ""
    return f"wrote {looked}{where}: sheet.png, density and albedo grids with scene.xml, EXR + PNG images, report.json"


def save_look(pipeline, spec: OutputSpec, request: RenderRequest, styles: dict, log: Callable[[str], None] = log):
    """Fit the look of ``request.save_look`` on the key frames of its one density, and write it
    (``styles``: path -> (decoded image, notes))."""
    from ..files import load_density_frames
    from ..look import LookSettings, parse_key_frames
    from ..progress import bar, fit_progress
    from ..style import Style

    source = request.sources[0]
    if request.mesh:
        from ..data.mesh import load_mesh, voxelize

        densities = [voxelize(*load_mesh(source), spec.mesh_res, supersample=2)]
        names = [Path(source).stem]
    else:
        loaded = load_density_frames(source, grid=spec.grid, up=spec.up, velocity_grid="")  # a fit needs none
        densities, names = loaded.densities, loaded.names
    frames = pipeline.frames(densities, None, names)
    keys = None if request.key_frames is None else parse_key_frames(request.key_frames, len(frames.densities))
    chosen = request.style_parts()
    style = Style(
        tuple(styles[path][0] for path, _ in chosen),
        tuple(weight for _, weight in chosen),
        tuple(Path(path).name for path, _ in chosen),
    )
    notes: list[str] = []
    steps = pipeline.settings.look_steps
    steps = LookSettings().steps if steps is None else steps
    with bar(steps, "fitting the look") as progress_bar:
        look = pipeline.fit_look(frames, style, key_frames=keys, notes=notes, progress=fit_progress(progress_bar))
    for note in notes:
        log(f"note: {note}")
    look.save(request.save_look)
    log(
        f"fitted the look on frame(s) {', '.join(map(str, look.meta['key_frames']))} in "
        f"{look.meta['fit_seconds']:.1f} s: {request.save_look}"
    )
    return look
