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
import sys
from pathlib import Path

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
from .resample import DEFAULT_WORKING_SIZE


def _coat(text: str) -> float:
    kind, colon, ior = text.partition(":")
    if kind != "dielectric" or (colon and not ior):
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
    group.add_argument(
        "--turntable",
        type=int,
        default=0,
        help="render N views around the orbit (a video; a sequence's frame i takes view i mod N)",
    )
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
        "--working-size",
        type=int,
        default=DEFAULT_WORKING_SIZE,
        metavar="N",
        help=f"stylize grids longer than N voxels on a side on a copy resampled to N, and path trace the full grid "
        f"with its albedo resampled back (default {DEFAULT_WORKING_SIZE}; 0: stylize the full grid)",
    )
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
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except OSError as error:
        from .files.paths import os_error_line

        print(f"error: {os_error_line(error, 'choose a writable --out')}", file=sys.stderr)
        return 2
    except RuntimeError as error:
        from .backend import BackendError

        if isinstance(error, BackendError):
            print(f"error: {error}", file=sys.stderr)
            return 2
        raise


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
        working_size=args.working_size,
        colour_match=args.colour_match,
        refine_steps=args.refine,
        refine_path_steps=args.refine_path,
        density_scale=args.density_scale,
        camera_distance=args.camera_distance,
        look_steps=args.look_steps,
        key_frames=args.key_frames if args.save_look is None else None,
        render=render,
    )


def output_spec(args):
    """The ``job.OutputSpec`` that ``args`` ask for."""
    from .job import OutputSpec

    return OutputSpec(grid=args.grid, up=args.up, mesh_res=args.mesh_res, fps=args.fps, vdb=args.vdb)


INPUTS_AND_OUTPUTS = ("density", "mesh", "style", "mix", "look", "save_look", "out", "frames")
"""The options that say what to render and where: a caller that passes the rest on (``shared_options``)
sets these itself."""


def shared_options(options: list[str], context: str, own: str, *, density: Path, out: Path, look=None, style=None):
    """mistyle-render's ``options`` as a caller that names the inputs and outputs itself passes them to
    every run it starts (mistyle-farm's options after ``--``, mistyle-preview's ``--render-options``):
    parsed by this command's parser around the caller's ``density``, ``out`` and ``look`` or ``style``, and
    checked as the command checks them (``check_options``). Returns the parsed options, for
    ``settings_from`` and ``output_spec``; ``ValueError`` (one line, ``context`` first) for an option the
    command would refuse, and for one of ``INPUTS_AND_OUTPUTS``, the caller's own (``own`` says so)."""

    def refuse(message: str):
        raise ValueError(f"{context}: {message}.")

    command = parser()
    command.error = refuse  # argparse's own would print the usage and exit
    given = ["--density", str(density), "--out", str(out)]
    given += ["--look", str(look)] if look is not None else ["--style", str(style)]
    alone, parsed = command.parse_args(given), command.parse_args(given + list(options))
    for name in INPUTS_AND_OUTPUTS:  # an option given again overrides (or extends) the caller's: compare
        if getattr(parsed, name) != getattr(alone, name):
            refuse(f"--{name.replace('_', '-')} is {own}")
    check_options(parsed)
    return parsed


def request_from(args):
    """The ``job.RenderRequest`` that ``args`` ask for: inputs and outputs (``check_options`` first)."""
    from .job import RenderRequest

    return RenderRequest(
        density=tuple(args.density or ()),
        mesh=tuple(args.mesh or ()),
        style=tuple(args.style or ()),
        mix=tuple(args.mix or ()),
        look=args.look,
        save_look=args.save_look,
        out=args.out,
        overwrite=args.overwrite,
        resume=args.resume,
        frame_range=args.frame_range,
        key_frames=args.key_frames,
    )


def run(args) -> int:
    from .job import render_outputs

    check_options(args)
    print(render_outputs(settings_from(args), output_spec(args), request_from(args)))
    return 0


# ---------------------------------------------------------------------------- stage 0: options
def check_options(args) -> None:
    """Every option's range, before anything is read or written; one message names the option.

    Options that a library function also takes are checked by that function's own validator."""
    from .files import check_link
    from .resample import validate_working_size
    from .scenes import validate_density_scale
    from .scenes.cameras import validate_camera_distance, validate_orbit_position
    from .scenes.pathtraced import validate_coat_ior, validate_max_depth
    from .stylizer import validate_scale_structures, validate_strength

    for path in args.density or []:  # a loop would end in Path.resolve's RuntimeError while planning outputs
        check_link(Path(path), "Density", "point --density at a density file or a folder of frames")
    for path in args.mesh or []:
        check_link(Path(path), "Mesh", "point --mesh at a mesh file")
    for path in (args.style or []) + [item.rpartition(":")[0] for item in args.mix or []]:
        check_link(Path(path), "Style image", "point --style at an image file or a folder of them")
    if args.look is not None:
        check_link(Path(args.look), "Look", "point --look at a look file made by --save-look")
    if args.vgg_weights is not None and not Path(args.vgg_weights).is_file():
        raise ValueError(f"--vgg-weights {args.vgg_weights} does not exist; point it at a VGG16 weights file.")
    validate_max_depth(args.max_depth, "--max-depth")
    validate_orbit_position(args.view, "--view")
    if args.camera_distance is not None:
        validate_camera_distance(args.camera_distance, "--camera-distance")
    if args.density_scale is not None:
        validate_density_scale(args.density_scale, "--density-scale")
    validate_scale_structures(args.scale_structures, "--scale-structures")
    validate_working_size(args.working_size, "--working-size")
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
    from .job.batch import check_look_replaceable

    if args.out is None and args.save_look is None:
        raise ValueError("--out is required (only --save-look alone, which writes the look file, needs none).")
    if args.resume and args.overwrite:
        raise ValueError("--resume keeps the complete outputs and --overwrite replaces them: give one of the two.")
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
    if args.look is not None and args.look_steps is not None:
        raise ValueError("--look-steps sets the steps of a look's fit; --look applies a look already fitted: drop one.")
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
if __name__ == "__main__":
    sys.exit(main())
