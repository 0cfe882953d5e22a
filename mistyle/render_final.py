"""``mistyle-render`` (``python -m mistyle.render_final``): stylize densities, meshes or sequences, path-trace them.

The method is ``mistyle.pipeline``; this module is argparse -> ``PipelineSettings`` -> ``Pipeline`` -> files.

    mistyle-render --density examples/smoke_64.vol --style examples/style_marble.png --out out/marble
    mistyle-render --density smoke.vol --style jade.png --coat dielectric:1.5 --turntable 24 --out out/jade
    mistyle-render --mesh bunny.ply --style marble.png --coat dielectric --out out/bunny
    mistyle-render --density data/fire/ --style lava.png --out out/fire             # a folder of frames
    mistyle-render --density houdini.vdb --grid density --style wave.png --out out/wave   # OpenVDB in and out
    mistyle-render --density a.vol b.vdb --style paintings/ --out out/batch          # every pair, index.html
    mistyle-render --density smoke.vol --mix wave.png:0.7 starry.png:0.3 --strength 0.6 --out out/mix

One output per (density, style) pair (``mistyle.outputs``): a single pair into ``--out``, several into
``--out/{density}__{style}/`` with ``--out/index.html``; an existing output is replaced only with
``--overwrite``. Each output holds:

- ``sheet.png``: style | the network (fast layer) | the output (path traced), with the metrics under them;
- ``density.vol`` and the path-traced albedo (``albedo.vol``, or ``albedo_refined.vol`` when refined),
  both with the medium box as bounding box, and ``scene.xml``, the Mitsuba 3 scene
  that reproduces the final render (``mi.load_file``; ``mistyle.scenes.export``) -- with ``--mesh``
  the density is the voxelized mesh; per frame ``*_frameNNNN.*`` for sequences;
- ``volume.vdb`` (OpenVDB: ``density`` and the albedo as ``Cd``) when the density came from a
  ``.vdb`` -- with that file's transform, so it drops back into Houdini or Blender -- or with
  ``--vdb``; ``albedo.npy`` (the feed-forward albedo: the network's, with the style's colours unless
  ``--no-colour-match``);
- per image ``*.exr`` (linear) and ``*.png`` (the training tone curve) and ``*_network_layer.png``
  (the fast layer's image of the feed-forward albedo under the training light), ``turntable.mp4``/``.gif``
  or ``sequence.mp4``/``.gif``;
- ``report.json`` with timings and the style metrics of the path-traced images against the style:
  ``rgb_swd``, ``patch_swd`` and ``hue_coverage`` (the fidelity benchmark's,
  ``objective.metrics.style_fidelity``), ``swd_final`` (sliced W2 of colours), ``swd_layer`` (the
  ``*_network_layer`` images), and for sequences ``temporal_flicker`` (the feed-forward frames) and
  ``temporal_flicker_look`` (the look's; ``*_unwarped`` when the frames carry no velocity).

``--strength`` (0: a uniform grey medium, 1: the full style) and ``--mix`` act on the network's
predicted stylizing kernels (``pipeline.Stylizer.kernels``); a mix is measured and refined against a
mosaic of its styles with areas in proportion to the weights (``style.style_target``). By default
at full strength a look is fitted on the frame, or on a sequence's first, middle and last frame, and
applied to every frame (``Pipeline.fits_look``, ``mistyle.look``), which is what makes the medium take
on the style's hues and patterns; naming
``--refine`` (fast-layer steps) or ``--refine-path`` (path-traced steps) refines the feed-forward
albedo against the style instead (``Pipeline.refinement``;
``docs/decisions/2026-11-25-style-fidelity-study.md``). ``--save-look``/``--look``/``--frames`` keep a
look in a file and apply it to chunks of a sequence that merge (``docs/looks.md``).
``--refine 0`` renders the feed-forward albedo: the network's arrangement with the style's colours
(``mistyle.colour_match``, no gradient step; ``--no-colour-match`` keeps the network's own colours).
Each output is written into a hidden staging folder beside it that replaces it only when complete, so a failed or
interrupted run leaves nothing half-written, and a second run into the same output is refused while
one is in progress. Progress bars (rates, time left) appear on a terminal only; ``--quiet`` keeps
only errors and the final line.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .conventions import (
    DEVICES,
    HELD_OUT_VIEW,
    IMAGE_SIDES,
    LIGHT_KINDS,
    MAX_FIT_STEPS,
    REFINE_LAYER_STEPS,
    REFINE_PATH_STEPS,
    UP_AXES,
)
from .denoise import DENOISERS, oidn_missing


def _coat(text: str) -> float:
    kind, _, ior = text.partition(":")
    if kind != "dielectric":
        raise argparse.ArgumentTypeError(f"--coat takes dielectric[:ior], e.g. dielectric:1.5; got {text!r}")
    try:
        return float(ior) if ior else 1.5
    except ValueError:
        raise argparse.ArgumentTypeError(f"--coat dielectric:<ior> needs a number, got {ior!r}") from None


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="mistyle-render", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    for add_options in (
        _input_options,
        _style_options,
        _look_options,
        _output_options,
        _network_options,
        _render_options,
        _stylize_options,
    ):
        add_options(p)
    return p


def _input_options(p: argparse.ArgumentParser) -> None:
    """The density (or mesh) inputs."""
    group = p.add_argument_group("inputs")
    source = group.add_mutually_exclusive_group(required=True)
    source.add_argument(
        "--density",
        type=Path,
        nargs="+",
        action="extend",
        help=".vol, .vdb, .npy or .npz densities (one output each), or a folder of frames",
    )
    source.add_argument("--mesh", type=Path, nargs="+", action="extend", help="closed .ply/.obj meshes, voxelized")
    group.add_argument(
        "--grid", default=None, help="the float grid to read from .vdb densities (default: 'density', or the only one)"
    )
    group.add_argument("--mesh-res", type=int, default=64, help="voxels along the mesh's longest side")


def _style_options(p: argparse.ArgumentParser) -> None:
    """What the medium takes its look from: style images, a mix or a look; the style's strength."""
    group = p.add_argument_group("style")
    styles = group.add_mutually_exclusive_group(required=True)
    styles.add_argument(
        "--style",
        type=Path,
        nargs="+",
        action="extend",
        help="style images (PNG/JPEG/EXR) or folders of them: one output each",
    )
    styles.add_argument(
        "--mix",
        nargs="+",
        action="extend",
        metavar="IMAGE:WEIGHT",
        help="one style mixed from several, e.g. --mix a.png:0.7 b.png:0.3 (weights normalised)",
    )
    styles.add_argument(
        "--look",
        type=Path,
        default=None,
        metavar="FILE",
        help="apply a look fitted with --save-look (no --style; no per-frame refinement unless --refine is given)",
    )
    group.add_argument("--strength", type=float, default=1.0, help="0: a uniform grey medium ... 1: the full style")


def _look_options(p: argparse.ArgumentParser) -> None:
    """Fitting a look once and rendering chunks of a sequence from it."""
    group = p.add_argument_group("looks and chunks")
    group.add_argument(
        "--save-look",
        type=Path,
        default=None,
        metavar="FILE",
        help="fit the style as a look on --key-frames of the density and write it to FILE; with --out, "
        "also render every frame from it",
    )
    group.add_argument(
        "--key-frames",
        default=None,
        metavar="I,J,...",
        help="0-based frames the look is fitted on, with --save-look or for the default output's look "
        "(default: the first, middle and last frame)",
    )
    group.add_argument(
        "--look-steps",
        type=int,
        default=None,
        metavar="STEPS",
        help="steps of a look's fit, with --save-look or for the default output's look (default: "
        "mistyle.look.LookSettings.steps)",
    )
    group.add_argument(
        "--frames",
        default=None,
        metavar="A-B",
        help="render only frames A to B (0-based, inclusive) of a sequence; files keep their index in the whole "
        "sequence, so chunks rendered into one --out merge there (each replaces only its own frames)",
    )


def _output_options(p: argparse.ArgumentParser) -> None:
    """Where outputs go and what may be replaced."""
    group = p.add_argument_group("outputs")
    group.add_argument("--out", type=Path, default=None, help="the output folder (optional with --save-look)")
    group.add_argument("--overwrite", action="store_true", help="replace outputs that already exist")
    group.add_argument(
        "--resume", action="store_true", help="keep the outputs already complete, make only the missing ones"
    )
    group.add_argument("--vdb", action="store_true", help="also write volume.vdb for densities that are not .vdb files")
    group.add_argument(
        "--up",
        choices=UP_AXES,
        default=None,
        help="the world up axis of the scene the .vdb files belong to: y (Houdini, Mitsuba) or z (Blender). "
        "Read .vdb densities are turned so that it is up in mistyle's renders, and volume.vdb is written in that "
        "world (default: what a mistyle .vdb records, else y)",
    )
    group.add_argument(
        "--quiet", action="store_true", help="no progress bars or status lines (errors are still printed)"
    )
    group.add_argument("--fps", type=int, default=12)


def _network_options(p: argparse.ArgumentParser) -> None:
    """The network and the device it runs on."""
    group = p.add_argument_group("network")
    group.add_argument("--checkpoint", type=Path, default=None, help="SKPN checkpoint (default: the bundled one)")
    group.add_argument("--vgg-weights", default=None, help="VGG16 weights, for checkpoints trained with VGG16")
    group.add_argument("--device", choices=DEVICES, default="cpu")


def _render_options(p: argparse.ArgumentParser) -> None:
    """The final render: camera, light, samples, medium."""
    from .scenes.bricks import DEFAULT_BRICK

    group = p.add_argument_group("final render")
    group.add_argument(
        "--view", type=float, default=HELD_OUT_VIEW, help="camera position on the training orbit, in [0, 1)"
    )
    group.add_argument("--turntable", type=int, default=0, help="render N frames around the orbit (a video)")
    group.add_argument("--camera-distance", type=float, default=None, help="orbit radius (default: the checkpoint's)")
    group.add_argument(
        "--light", default=LIGHT_KINDS[0], help="constant[:Le] | envmap:<file.exr>[:scale] | point:x,y,z[:I] | area[:L]"
    )
    group.add_argument("--spp", type=int, default=64)
    group.add_argument("--max-depth", type=int, default=-1, help="-1: full multiple scattering; 2: single scattering")
    group.add_argument(
        "--denoise",
        choices=DENOISERS,
        default=DENOISERS[0],
        help="oidn: denoise the path-traced images with Intel Open Image Denoise, guided by the albedo the "
        "camera sees (default); none: the path tracer's images as they are",
    )
    group.add_argument("--res", type=int, default=256)
    group.add_argument(
        "--density-scale", type=float, default=None, help="extinction per unit density (default: training's)"
    )
    group.add_argument(
        "--coat", type=_coat, default=None, metavar="dielectric[:ior]", help="smooth dielectric boundary"
    )
    group.add_argument(
        "--bricks",
        type=int,
        default=None,
        metavar="VOXELS",
        help=f"path-trace the medium as bricks of this many voxels, each with its own majorant (default "
        f"{DEFAULT_BRICK}; 0: one medium; always 0 with --coat)",
    )


def _stylize_options(p: argparse.ArgumentParser) -> None:
    """How the albedo is made beyond the network."""
    group = p.add_argument_group("stylization")
    group.add_argument("--scale-structures", type=float, default=1.0, help="resample the density by f before stylizing")
    group.add_argument(
        "--no-colour-match",
        dest="colour_match",
        action="store_false",
        help="keep the network's own colours (default: its arrangement gets the style's colours, mistyle.colour_match)",
    )
    group.add_argument(
        "--refine",
        type=int,
        default=None,
        metavar="STEPS",
        help=f"refine the albedo for STEPS steps against the style through the fast layer "
        f"(default: 0, a look fitted on the frame or a sequence's key frames instead; {REFINE_LAYER_STEPS} "
        "for a single frame with --no-colour-match)",
    )
    group.add_argument(
        "--refine-path",
        type=int,
        default=None,
        metavar="STEPS",
        help=f"then STEPS steps with the path tracer in the loop (multiple scattering; default: "
        f"0, or {REFINE_PATH_STEPS} for a single frame at full strength with --no-colour-match)",
    )


def main(argv=None) -> int:
    from .progress import set_quiet
    from .stops import run_stoppable

    args = parser().parse_args(argv)
    set_quiet(args.quiet)
    try:
        return run_stoppable(
            lambda: run(args),
            "the output being written was removed; finished outputs are kept",
            in_process=argv is not None,
        )
    except (ValueError, OSError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except RuntimeError as error:
        from .backend import BackendError

        if isinstance(error, BackendError):
            print(f"error: {error}", file=sys.stderr)
            return 2
        raise


def log(message: str) -> None:
    from .progress import status

    status(message)


def settings_from(args):
    """The ``pipeline.PipelineSettings`` that ``args`` ask for."""
    from .pipeline import PipelineSettings, RenderSettings

    render = RenderSettings(
        res=args.res,
        spp=args.spp,
        max_depth=args.max_depth,
        light=args.light,
        coat_ior=args.coat,
        bricks=args.bricks,
        view=args.view,
        turntable=args.turntable,
        denoise=args.denoise,
    )
    return PipelineSettings(
        checkpoint=args.checkpoint,
        device=args.device,
        vgg_weights=args.vgg_weights,
        strength=args.strength,
        scale_structures=args.scale_structures,
        colour_match=args.colour_match,
        refine_steps=args.refine,
        refine_path_steps=args.refine_path,
        density_scale=args.density_scale,
        camera_distance=args.camera_distance,
        look_steps=args.look_steps,
        key_frames=args.key_frames if args.save_look is None else None,
        render=render,
    )


@dataclass
class Job:
    """One output's inputs, loaded and checked before any heavy work (``load``), and where it goes."""

    args: argparse.Namespace
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


def run(args) -> int:
    from .backend import use_variant
    from .io import load_style
    from .outputs import is_mistyle_output, plan_outputs
    from .ownership import chunk_staging, output_lock, staged_directory
    from .pipeline import Pipeline

    check_options(args)
    look_mode = args.look is not None or args.save_look is not None
    sources = args.density or args.mesh
    # A look's sequence, and any --frames chunk, merges frame by frame into its folder.
    merging = args.frame_range is not None or (look_mode and all(Path(p).is_dir() for p in sources))
    planned = []
    if args.out is not None:
        styles_given = [args.look] if args.look is not None else args.style
        planned = plan_outputs(
            args.density, args.mesh, styles_given, args.mix, args.out, args.overwrite or merging, args.resume
        )
    keep = args.resume and not args.overwrite and not merging
    outputs = [output for output in planned if not (keep and is_mistyle_output(output.folder))]
    for output in planned:
        if output not in outputs:
            check_same_settings(args, output.folder, "--resume keeps it", "pass --overwrite to render it again")
    batch = len(planned) > 1
    if len(outputs) < len(planned):
        log(f"note: --resume: {len(planned) - len(outputs)} of {len(planned)} output(s) already complete, kept")
    for source in dict.fromkeys(sources):
        if not Path(source).exists():
            raise ValueError(f"{'Mesh' if args.mesh else 'Density'} {source} does not exist.")
    styles = {}
    if args.look is None:
        # Every input is looked at before the first output is made, so a bad file late in a batch
        # does not stop it half way (each density is read in full when its turn comes). Each style is
        # decoded once, with the notes on its conversion.
        images = [image for output in outputs for image, _ in output.style.parts]
        if args.save_look is not None:
            images = [path for path, _ in _look_style_parts(args)]
        for path in dict.fromkeys(images):
            notes: list[str] = []
            styles[path] = (load_style(path, notes), notes)
            for note in notes:
                log(f"note: {note}")
    if args.vdb or any(output.density.path.suffix.lower() == ".vdb" for output in outputs):
        from .vdb import vdb_interpreter

        vdb_interpreter()  # no OpenVDB binding: say so before any work
    use_variant(args.device)
    pipeline = Pipeline(settings_from(args), log=log)
    look = None
    if args.look is not None:
        from .look import Look

        look = Look.load(args.look, stylizer=pipeline.stylizer)
        styles[args.look] = (look.style, [])
    elif args.save_look is not None:
        look = save_look(args, pipeline, styles)
        if not outputs:
            print(f"wrote the look {args.save_look}")
            return 0
        for output in outputs:
            styles[output.style.parts[0][0]] = (look.style, [])
    try:
        for number, output in enumerate(outputs, 1):
            if batch:
                log(f"[{number}/{len(outputs)}] {output.name}")
            job = load(args, output, pipeline, styles)
            job.look, job.merged = look, merging
            if merging:
                check_mergeable(job)
                with chunk_staging(output.folder) as staging:
                    job.out = staging
                    render_job(job)
                    with output_lock(output.folder, wait=True) as (folder, _):
                        merge_chunk(job, folder)
            else:
                # Everything is written into a staging folder that replaces the output only when it is complete.
                with staged_directory(output.folder) as staging:
                    job.out = staging
                    render_job(job)
    finally:
        if batch:  # also when a pair failed: the index shows the outputs that are complete
            write_batch_index(args.out, pipeline)
    where = f"{args.out}/ ({len(planned)} outputs and index.html)" if batch else f"{args.out}/"
    looked = f"the look {args.save_look}, and " if args.save_look is not None else ""
    print(f"wrote {looked}{where}: sheet.png, density and albedo grids with scene.xml, EXR + PNG images, report.json")
    return 0


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


def _look_style_parts(args) -> list[tuple[Path, float]]:
    """The style a look is fitted to: ``--style``'s one image, or ``--mix``'s images and weights."""
    from .outputs import style_choices

    (choice,) = style_choices(args.style, args.mix)
    return list(choice.parts)


def save_look(args, pipeline, styles: dict):
    """Fit the look of ``--save-look`` on the key frames of the one density, and write it."""
    from .io import load_density_frames
    from .look import LookSettings, parse_key_frames
    from .progress import bar, fit_progress
    from .style import Style

    source = (args.density or args.mesh)[0]
    if args.mesh:
        from .data.mesh import load_mesh, voxelize

        densities = [voxelize(*load_mesh(source), args.mesh_res, supersample=2)]
        names = [Path(source).stem]
    else:
        loaded = load_density_frames(source, grid=args.grid, up=args.up, velocity_grid="")  # a fit needs none
        densities, names = loaded.densities, loaded.names
    frames = pipeline.frames(densities, None, names)
    keys = None if args.key_frames is None else parse_key_frames(args.key_frames, len(frames.densities))
    chosen = _look_style_parts(args)
    style = Style(
        tuple(styles[path][0] for path, _ in chosen),
        tuple(weight for _, weight in chosen),
        tuple(Path(path).name for path, _ in chosen),
    )
    notes: list[str] = []
    steps = LookSettings().steps if args.look_steps is None else args.look_steps
    with bar(steps, "fitting the look") as progress_bar:
        look = pipeline.fit_look(
            frames,
            style,
            key_frames=keys,
            notes=notes,
            progress=fit_progress(progress_bar),
        )
    for note in notes:
        log(f"note: {note}")
    look.save(args.save_look)
    log(
        f"fitted the look on frame(s) {', '.join(map(str, look.meta['key_frames']))} in "
        f"{look.meta['fit_seconds']:.1f} s: {args.save_look}"
    )
    return look


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


# ---------------------------------------------------------------------------- stage 0: options
def check_options(args) -> None:
    """Every option's range, before anything is read or written; one message names the option.

    Options that a library function also takes are checked by that function's own validator."""
    from .io import check_link
    from .pipeline import validate_scale_structures, validate_strength
    from .scenes import validate_density_scale
    from .scenes.cameras import validate_camera_distance, validate_orbit_position
    from .scenes.pathtraced import validate_coat_ior, validate_max_depth

    for path in args.density or []:  # a loop would end in Path.resolve's RuntimeError while planning outputs
        check_link(Path(path), "Density", "point --density at a density file or a folder of frames")
    for path in args.mesh or []:
        check_link(Path(path), "Mesh", "point --mesh at a mesh file")
    for path in (args.style or []) + [item.rpartition(":")[0] for item in args.mix or []]:
        check_link(Path(path), "Style image", "point --style at an image file or a folder of them")
    if args.look is not None:
        check_link(Path(args.look), "Look", "point --look at a look file made by --save-look")
    validate_max_depth(args.max_depth, "--max-depth")
    validate_orbit_position(args.view, "--view")
    if args.camera_distance is not None:
        validate_camera_distance(args.camera_distance, "--camera-distance")
    if args.density_scale is not None:
        validate_density_scale(args.density_scale, "--density-scale")
    validate_scale_structures(args.scale_structures, "--scale-structures")
    validate_coat_ior(args.coat, "--coat dielectric:<ior>")
    validate_strength(args.strength, "--strength")
    missing_denoiser = oidn_missing() if args.denoise == "oidn" else None
    checks = [
        (1 <= args.spp <= 1 << 16, f"--spp must lie in [1, 65536], got {args.spp}"),
        (IMAGE_SIDES[0] <= args.res <= IMAGE_SIDES[1], f"--res must lie in {list(IMAGE_SIDES)}, got {args.res}"),
        (0 <= args.turntable <= 3600, f"--turntable must lie in [0, 3600] frames, got {args.turntable}"),
        (1 <= args.fps <= 240, f"--fps must lie in [1, 240], got {args.fps}"),
        (
            args.refine is None or 0 <= args.refine <= MAX_FIT_STEPS,
            f"--refine must lie in [0, {MAX_FIT_STEPS}] steps, got {args.refine}",
        ),
        (
            args.refine_path is None or 0 <= args.refine_path <= MAX_FIT_STEPS,
            f"--refine-path must lie in [0, {MAX_FIT_STEPS}] steps, got {args.refine_path}",
        ),
        (8 <= args.mesh_res <= 512, f"--mesh-res must lie in [8, 512], got {args.mesh_res}"),
        (args.bricks is None or 0 <= args.bricks <= 4096, f"--bricks must lie in [0, 4096] voxels, got {args.bricks}"),
        (
            not (args.bricks and args.coat is not None),
            "--bricks needs one medium under --coat (the coat is an optical boundary on the box); drop --bricks",
        ),
        (args.denoise != "oidn" or missing_denoiser is None, missing_denoiser or ""),
    ]
    for ok, message in checks:
        if not ok:
            raise ValueError(message + ".")
    check_look_options(args)


def check_look_options(args) -> None:
    """The options of looks and frame chunks, together (``--save-look``, ``--look``, ``--key-frames``, ``--frames``)."""
    if args.out is None and args.save_look is None:
        raise ValueError("--out is required (only --save-look alone, which writes the look file, needs none).")
    sources = (args.density or []) + (args.mesh or [])
    if args.save_look is not None:
        if args.look is not None:
            raise ValueError("--save-look fits a new look from --style; it does not take --look.")
        if len(sources) != 1:
            raise ValueError(
                f"--save-look fits one look on one density (a file or a folder of frames); got {len(sources)}."
            )
        if args.style and (len(args.style) != 1 or Path(args.style[0]).is_dir()):
            raise ValueError("--save-look fits one style: give one --style image (or one --mix).")
        if args.strength != 1.0:
            raise ValueError("A look holds its style at full strength; --save-look does not take --strength.")
    if args.look is not None and Path(args.look).is_dir():
        raise ValueError(
            f"--look {args.look} is a folder; give a look file, made by mistyle-render ... --save-look FILE."
        )
    if args.look is not None and args.strength != 1.0:
        raise ValueError("A look holds its style at full strength; --look does not take --strength.")
    if args.key_frames is not None and args.save_look is None:
        if args.look is not None or not settings_from(args).fits_look:
            raise ValueError(
                "--key-frames chooses the frames a look is fitted on: with --save-look, or for the default output's "
                "look, which --look, --refine, --refine-path, --strength below 1 and --no-colour-match leave out."
            )
    if args.look_steps is not None and not 0 <= args.look_steps <= MAX_FIT_STEPS:
        raise ValueError(f"--look-steps must lie in [0, {MAX_FIT_STEPS}], got {args.look_steps}.")
    if args.save_look is not None:
        path = Path(args.save_look)
        if path.is_dir() or not path.parent.is_dir():
            raise ValueError(
                f"--save-look {path} must be a file in an existing folder (e.g. looks/wave.look); "
                f"{'it is a folder' if path.is_dir() else 'its folder does not exist'}."
            )
        check_look_replaceable(path, args.overwrite)
    if args.frames is not None:
        args.frame_range = parse_frame_range(args.frames)
        if args.mesh:
            raise ValueError("--frames selects frames of a density sequence; a mesh has one frame.")
        if args.look is None and args.save_look is None:
            raise ValueError(
                "--frames renders chunks from a look file, so that every chunk matches the others (from a style, "
                "each chunk would fit its own look on its own frames): add --look FILE, or --save-look FILE to fit one."
            )
    else:
        args.frame_range = None


def check_look_replaceable(path: Path, overwrite: bool) -> None:
    """``ValueError`` unless ``--save-look path`` may be written: a new file, or with ``--overwrite`` a look."""
    from .look import is_look_file

    if not (path.exists() or path.is_symlink()):
        return
    if not is_look_file(path):
        raise ValueError(
            f"--save-look {path} already exists and is not a mistyle look; mistyle replaces only its own files. "
            "Choose another file name."
        )
    if not overwrite:
        raise ValueError(f"The look {path} already exists; pass --overwrite to replace it, or choose another name.")


def parse_frame_range(text: str) -> tuple[int, int]:
    """``--frames A-B`` (or ``A``): the 0-based, inclusive range ``(A, B)``."""
    first, dash, last = str(text).partition("-")
    try:
        first, last = int(first), int(last) if dash else int(first)
    except ValueError:
        raise ValueError(f"--frames takes A-B (0-based, inclusive), e.g. --frames 0-49; got {text!r}.") from None
    if first < 0 or last < first:
        raise ValueError(f"--frames A-B needs 0 <= A <= B, got {text!r}.")
    return first, last


# ---------------------------------------------------------------------------- stage 1: load and check
def load(args, output, pipeline, styles: dict) -> Job:
    """Check and load one output's inputs (``styles``: path -> (decoded image, conversion notes));
    nothing heavy runs before this returns."""
    from .io import density_frame_files, load_density_frames
    from .style import Style

    notes = [note for path, _ in output.style.parts for note in styles[path][1]]
    style = Style(
        tuple(styles[path][0] for path, _ in output.style.parts),
        tuple(weight for _, weight in output.style.parts),
        tuple(Path(path).name for path, _ in output.style.parts),
    )
    pipeline.light()  # a bad --light fails here, before the density is read
    coat_mesh, transforms, sources, up = None, None, None, args.up or "y"
    if output.density.mesh:
        from .data.mesh import fit_to_box, load_mesh, voxelize

        vertices, faces = load_mesh(output.density.path)
        densities, velocities, names = (
            [voxelize(vertices, faces, args.mesh_res, supersample=2)],
            None,
            [output.density.name],
        )
        if args.coat is not None:
            placed, _ = fit_to_box(np.asarray(vertices, np.float64), args.mesh_res, 0.05)
            coat_mesh = (placed, faces)
    else:
        # notes: a VDB sequence's velocity units and frame rate as assumed, frames without a velocity
        loaded = load_density_frames(output.density.path, grid=args.grid, up=args.up, notes=notes)
        densities, velocities, names, transforms = loaded.densities, loaded.velocities, loaded.names, loaded.transforms
        up = loaded.up or up
        if transforms is not None:
            sources = density_frame_files(output.density.path)
    total, first = len(densities), 0
    if args.frame_range is not None:
        first, last = args.frame_range
        if last >= total:
            raise ValueError(f"--frames {first}-{last} lies outside {output.density.path}'s frames 0-{total - 1}.")
        chosen = slice(first, last + 1)
        densities, names = densities[chosen], names[chosen]
        velocities = None if velocities is None else velocities[chosen]
        transforms = None if transforms is None else transforms[chosen]
        sources = None if sources is None else sources[chosen]
    frames = pipeline.frames(densities, velocities, names)
    return Job(
        args=args,
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


def write_coat_mesh(job: Job) -> None:
    """The coat of ``--mesh ... --coat``, placed in the medium box, as the path tracer reads it."""
    from .data.mesh import write_ply

    if job.coat_mesh is not None:
        job.coat_mesh_path = write_ply(job.out / "coat_mesh.ply", *job.coat_mesh)


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


def _settings_record(args) -> dict:
    record = {
        "res": args.res,
        "spp": args.spp,
        "denoise": args.denoise,
        "max_depth": args.max_depth,
        "light": args.light,
        "coat_ior": args.coat,
        "view": args.view,
        "turntable": args.turntable,
        "strength": args.strength,
        "scale_structures": args.scale_structures,
        "colour_match": args.colour_match,
    }
    assert record.keys() == SETTING_OPTIONS.keys()
    return json.loads(json.dumps(record))  # as a report holds them (tuples become lists)


def check_same_settings(args, folder: Path, why: str, other_fix: str = "") -> None:
    """``ValueError`` naming the first option whose value differs from the one ``folder``'s render used."""
    from .outputs import REPORT_FILE

    try:
        held = json.loads((folder / REPORT_FILE).read_text()).get("inputs", {})
    except (OSError, ValueError, AttributeError):
        raise ValueError(
            f"{folder / REPORT_FILE} cannot be read, so the render settings of {folder} are unknown; "
            f"{other_fix or 'remove that folder'}, or choose another --out."
        ) from None
    for key, value in _settings_record(args).items():
        if key in held and held[key] != value:
            option, fixes = SETTING_OPTIONS[key], ", ".join(filter(None, [other_fix, "or choose another --out"]))
            raise ValueError(
                f"{folder} was rendered with {option} {held[key]} and this run asks for {value}; {why} only with the "
                f"same settings: give {option} {held[key]}, {fixes}."
            )


def _inputs_record(job: Job) -> dict:
    args, pipeline = job.args, job.pipeline
    refinement = pipeline.look_refinement() if job.look is not None else pipeline.refinement(len(job.frames.densities))
    return {
        "density": str(job.output.density.path),
        "mesh": job.output.density.mesh,
        "grid": args.grid,
        "style": job.look.meta.get("style", "a look") if job.look is not None else job.output.style.describe(),
        "frames": len(job.frames.densities),
        "shape_zyx": list(job.frames.densities[0].shape),
        "checkpoint": str(pipeline.stylizer.path),
        "look_sha256": None if job.look is None else job.look.meta.get("file_sha256"),
        **_settings_record(args),
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
    from .io import write_npy

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
    from .io import write_exr, write_gif, write_mp4, write_png
    from .progress import bar
    from .tone import display

    args, pipeline = job.args, job.pipeline
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
    log(f"path traced {total} image(s) of {args.res}^2 at {args.spp} spp in {report['render_seconds']:.1f} s")
    report["render_seconds_per_image"] = float(np.mean(render_seconds))

    kind = "sequence" if job.sequence else "turntable" if args.turntable else "view"
    for index, image in enumerate(images):
        stem = f"{kind}_{job.first + index:04d}" if len(images) > 1 or job.merged else "final"
        write_exr(job.out / f"{stem}.exr", image)
        write_png(job.out / f"{stem}.png", display(image), srgb=False)
        write_png(job.out / f"{stem}_network_layer.png", display(layer_images[index]), srgb=False)
    if len(images) > 1 and not job.merged:  # a merged folder's video is made of all its frames (merge_chunk)
        frames = [(display(image) * 255 + 0.5).astype(np.uint8) for image in images]
        report["video"] = [
            write_mp4(job.out / f"{kind}.mp4", frames, args.fps).name,
            write_gif(job.out / f"{kind}.gif", frames, args.fps).name,
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
        if job.transforms is not None or job.args.vdb:
            from .vdb import (
                ALBEDO_GRID,
                DENSITY_GRID,
                VdbTransform,
                mistyle_metadata,
                passenger_grids,
                passengers_at,
                write_vdb,
            )

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
                found, skipped = passenger_grids(job.sources[frame], job.args.grid)
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
    from .io import atomic_write_bytes
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

    refinement = stylized.refinement
    if stylized.look is not None:
        key_frames = ",".join(map(str, stylized.look.meta["key_frames"]))
        stage = f"a look fitted on key frames {key_frames}" if job.sequence else "a look fitted on the frame"
    else:
        stage = f"refine {refinement.layer_steps}+{refinement.path_steps} steps"
    lines = [
        f"{job.output.density.path.name} x {job.output.style.describe(names_only=True)}"[:110],
        f"RGB SWD {shown('rgb_swd', 4)}   patch SWD {shown('patch_swd', 4)}   hue coverage {shown('hue_coverage', 2)}",
        f"strength {job.args.strength:g}, {stage}, {job.args.res}^2 x {job.args.spp} spp, {seconds:.1f} s",
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
    check_same_settings(job.args, folder, "a chunk merges into it")


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
    from .io import atomic_write_bytes, read_png, write_gif, write_mp4
    from .outputs import REPORT_FILE
    from .ownership import merge_files
    from .pages import SHEET_FILE, write_index, write_sheet

    chunk = job.report
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
            write_mp4(folder / "sequence.mp4", shown, job.args.fps).name,
            write_gif(folder / "sequence.gif", shown, job.args.fps).name,
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
        f"first frame {frames and next(iter(frames))} shown; {job.args.res}^2 x {job.args.spp} spp",
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


if __name__ == "__main__":
    sys.exit(main())
