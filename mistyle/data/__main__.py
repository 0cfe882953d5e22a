"""``mistyle-data`` (``python -m mistyle.data``): generate mistyle's training and demo data offline.

python -m mistyle.data smoke --res 64 --plumes 100 --frames 90 --out data/smoke64
python -m mistyle.data smoke --res 128 --plumes 20 --frames 90 --crop 64 --out data/smoke128
python -m mistyle.data smoke ... --shard 0/4      # one of four processes or machines
python -m mistyle.data fire --res 64 --frames 120 --out data/fire
python -m mistyle.data styles --out data/styles
python -m mistyle.data mesh --mesh bunny.ply --res 64 --out bunny.vol
"""

from __future__ import annotations

import argparse
import errno
import sys
from pathlib import Path

from ..conventions import DEFAULT_DENSITY_SCALE, DEVICES, LS_DIRECTIONS


def _shard(text: str) -> tuple[int, int]:
    try:
        index, count = (int(part) for part in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--shard takes i/n, e.g. 0/4; got {text!r}") from None
    if count < 1 or not 0 <= index < count:
        raise argparse.ArgumentTypeError(f"--shard i/n needs 0 <= i < n, got {text!r}")
    return index, count


def _frames(text: str) -> tuple[int, int]:
    try:
        first, last = (int(part) for part in text.split("-"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--keep takes first-last, e.g. 61-90; got {text!r}") from None
    return first, last


RES_RANGE = {"smoke": (8, 256), "fire": (8, 256), "mesh": (8, 512)}
"""Grid sizes each command accepts: a 256^3 simulation holds a few GB of fields; 512^3 voxels as mistyle-render."""


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="mistyle-data", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--quiet", action="store_true", help="no progress bars or status lines (errors are still printed)"
    )
    commands = parser.add_subparsers(dest="command", required=True)
    smoke = commands.add_parser("smoke", help="simulate smoke plumes and write density/velocity/Ls frames")
    smoke.add_argument("--res", type=int, default=64, help="simulation resolution (cubic)")
    smoke.add_argument("--plumes", type=int, default=100)
    smoke.add_argument("--frames", type=int, default=90, help="frames simulated per plume")
    smoke.add_argument(
        "--keep", type=_frames, default=None, help="kept frames, first-last (1-based); default: the last third"
    )
    smoke.add_argument(
        "--crop", type=int, default=0, help="store random crops of this size (for high-resolution plumes)"
    )
    smoke.add_argument("--crops-per-frame", type=int, default=5)
    smoke.add_argument("--seed", type=int, default=0)
    smoke.add_argument(
        "--density-scale", type=float, default=DEFAULT_DENSITY_SCALE, help="extinction scale the cached Ls is made for"
    )
    smoke.add_argument("--directions", type=int, default=LS_DIRECTIONS, help="K for the cached Ls")
    smoke.add_argument("--shard", type=_shard, default=(0, 1), help="i/n: this process's share of the plumes")
    smoke.add_argument(
        "--device",
        choices=DEVICES,
        default=None,
        help="Mitsuba variant of the Ls precompute: cpu (llvm_ad_rgb) or cuda (cuda_ad_rgb); "
        "default: $MISTYLE_DEVICE, else cpu",
    )
    smoke.add_argument("--out", type=Path, required=True)
    fire = commands.add_parser("fire", help="simulate a burning plume and write its flame density frames")
    fire.add_argument("--res", type=int, default=64)
    fire.add_argument("--frames", type=int, default=120)
    fire.add_argument(
        "--keep", type=_frames, default=None, help="kept frames, first-last (1-based); default: the last half"
    )
    fire.add_argument("--seed", type=int, default=0)
    fire.add_argument("--out", type=Path, required=True)
    styles = commands.add_parser("styles", help="write the offline default style set as PNGs, with a summary")
    styles.add_argument("--size", type=int, default=128)
    styles.add_argument("--seed", type=int, default=0)
    styles.add_argument("--out", type=Path, required=True)
    tiny = commands.add_parser("tiny", help="the tiny fixed dataset for tests and CI (seconds)")
    tiny.add_argument("--device", choices=DEVICES, default=None, help="as for smoke")
    tiny.add_argument("--out", type=Path, required=True)
    mesh = commands.add_parser("mesh", help="voxelize a closed .ply/.obj mesh into a density (.vol or .npy)")
    mesh.add_argument("--mesh", type=Path, default=None, help="closed triangle mesh; default: a generated icosphere")
    mesh.add_argument("--res", type=int, default=64, help="voxels along the longest side")
    mesh.add_argument("--margin", type=float, default=0.05, help="empty border per side, fraction of the box")
    mesh.add_argument("--supersample", type=int, default=2, help="s: s^3 inside tests per voxel (soft edge)")
    mesh.add_argument("--out", type=Path, required=True, help="output .vol or .npy")
    args = parser.parse_args(argv)
    from ..progress import set_quiet

    set_quiet(args.quiet)
    from ..stops import run_stoppable

    kept = f"the files finished so far under {args.out} are kept, none half-written; run the same command again"
    return run_stoppable(lambda: _command(args), kept, in_process=argv is not None)


def _command(args) -> int:
    """The chosen command's work; 2 for bad input, after one line on stderr."""
    low, high = RES_RANGE[args.command] if args.command in RES_RANGE else (None, None)
    if low is not None and not low <= args.res <= high:
        print(f"error: --res must lie in [{low}, {high}] for {args.command}, got {args.res}.", file=sys.stderr)
        return 2
    if args.command in ("smoke", "fire") and args.frames < 1:
        print(f"error: --frames must be at least 1, got {args.frames}.", file=sys.stderr)
        return 2
    if args.command == "mesh":
        return _mesh_command(args)
    if getattr(args, "device", None):
        from ..backend import BackendError, use_variant

        try:
            use_variant(args.device)
        except BackendError as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
    if args.command == "tiny":
        from .tiny import make_tiny_dataset

        print(f"wrote {make_tiny_dataset(args.out)}")
        return 0
    if args.command == "styles":
        import json

        from ..io import atomic_write_bytes, write_png
        from .styles import offline_style_set, style_set_diversity

        styles = offline_style_set(size=args.size, seed=args.seed)
        for name, image in styles:
            write_png(args.out / f"{name}.png", image, srgb=False)  # already sRGB-encoded
        summary = style_set_diversity(styles)
        atomic_write_bytes(args.out / "styles.json", (json.dumps(summary, indent=1) + "\n").encode())
        print(json.dumps(summary))
        return 0
    if args.command == "fire":
        from .generate import generate_fire

        keep = args.keep or (args.frames // 2 + 1, args.frames)
        try:
            generate_fire(args.res, args.frames, keep, args.out, args.seed)
        except ValueError as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
        return 0

    from .generate import SmokeDatasetSpec, generate_smoke

    first, last = args.keep if args.keep else (args.frames - max(1, args.frames // 3) + 1, args.frames)
    spec = SmokeDatasetSpec(
        resolution=args.res,
        plumes=args.plumes,
        frames=args.frames,
        keep_first=first,
        keep_last=last,
        crop=args.crop,
        crops_per_frame=args.crops_per_frame,
        seed=args.seed,
        density_scale=args.density_scale,
        directions=args.directions,
    )
    from ..backend import BackendError

    try:
        manifest = generate_smoke(spec, args.out, args.shard)
    except (ValueError, BackendError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except OSError as error:
        if error.errno == errno.ENOSPC:
            print(
                f"error: the disk under {args.out} is full; free space and re-run the same command "
                "(finished files are kept, none is half-written).",
                file=sys.stderr,
            )
        else:
            print(f"error: cannot write under {args.out}: {error}", file=sys.stderr)
        return 1
    print(f"wrote {manifest}")
    return 0


def _mesh_command(args) -> int:
    from ..io import write_npy, write_vol
    from ..scenes.box import MediumBox
    from .mesh import icosphere, load_mesh, voxelize

    try:
        vertices, faces = load_mesh(args.mesh) if args.mesh else icosphere(4)
        density = voxelize(vertices, faces, args.res, args.margin, args.supersample)
        suffix = args.out.suffix.lower()
        if suffix == ".vol":
            box = MediumBox(density.shape)
            write_vol(args.out, density, box.bbox_min, box.bbox_max)
        elif suffix == ".npy":
            write_npy(args.out, density)
        else:
            raise ValueError(f"--out must end in .vol or .npy, got {args.out}.")
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}: density {density.shape} (Z, Y, X), {float((density > 0).mean()):.1%} occupied")
    return 0


if __name__ == "__main__":
    sys.exit(main())
