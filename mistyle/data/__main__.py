"""``mistyle-data`` (``python -m mistyle.data``): generate mistyle's training and demo data offline.

python -m mistyle.data smoke --res 64 --plumes 100 --frames 90 --out data/smoke64
python -m mistyle.data smoke --res 128 --plumes 20 --frames 90 --crop 64 --out data/smoke128
python -m mistyle.data smoke ... --shard 0/4      # one of four processes or machines
python -m mistyle.data fire --res 64 --frames 120 --out data/fire
python -m mistyle.data styles --out data/styles
python -m mistyle.data mesh --mesh bunny.ply --res 64 --out bunny.vol

Every option's range is checked before any work, with one line naming the option. A dataset folder
is mistyle's own (``mistyle.ownership``): it carries a manifest of the files written there, and a
folder holding a file mistyle did not write is refused; a folder an older mistyle wrote (no manifest,
nothing but its layout's files) is taken over as it is. ``smoke`` and ``fire`` keep the frames already
there (a re-run completes a dataset); ``tiny`` is made whole beside its folder and replaces it.
``mesh`` writes one new file and never replaces one.
"""

from __future__ import annotations

import argparse
import errno
import re
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
STYLE_SIZE_RANGE = (8, 512)
"""``styles --size``: the set's 336 images are held at once, 1 GB at 512^2."""
MAX_SEED = 2**31 - 1
DATASET_KIND = "dataset"
LAYOUTS = {
    "smoke": re.compile(r"manifest(\.shard-\d+-of-\d+)?\.json|plume\d{4}/frame\d{4}(_crop\d+)?\.npz"),
    "fire": re.compile(r"frame\d{4}\.npz"),
    "styles": re.compile(r"(photo|texture|material|painting)/[A-Za-z0-9_.-]+\.png|styles\.json"),
    "tiny": re.compile(r"smoke/(manifest\.json|plume\d{4}/frame\d{4}\.npz)|styles/[A-Za-z0-9_.-]+\.png"),
}
"""The files each command writes into ``--out``: what a folder of an older mistyle's (no manifest) may hold."""


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
    styles.add_argument(
        "--size", type=int, default=128, help=f"side in pixels, in [{STYLE_SIZE_RANGE[0]}, {STYLE_SIZE_RANGE[1]}]"
    )
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
    mesh.add_argument("--out", type=Path, required=True, help="output .vol or .npy (a new file)")
    args = parser.parse_args(argv)
    from ..progress import set_quiet

    set_quiet(args.quiet)
    from ..stops import run_stoppable

    kept = f"the files finished so far under {args.out} are kept, none half-written; run the same command again"
    try:
        check_options(args)
        return run_stoppable(lambda: _command(args), kept, in_process=argv is not None)
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except OSError as error:
        from ..files.paths import os_error_line

        print(f"error: {os_error_line(error, 'choose a writable --out')}", file=sys.stderr)
        return 2


def check_options(args) -> None:
    """Every option's range, before anything is read or written: ``ValueError`` naming the option."""
    from ..scenes.medium import validate_density_scale

    low, high = RES_RANGE.get(args.command, (None, None))
    checks = []
    if low is not None:
        checks.append(
            (low <= args.res <= high, f"--res must lie in [{low}, {high}] for {args.command}, got {args.res}")
        )
    if args.command in ("smoke", "fire"):
        least = 2 if args.command == "smoke" else 1  # smoke trains on pairs of consecutive frames
        checks.append((least <= args.frames <= 10000, f"--frames must lie in [{least}, 10000], got {args.frames}"))
        if args.keep is not None:
            first, last = args.keep
            checks.append(
                (
                    1 <= first <= last <= args.frames,
                    f"--keep {first}-{last}: the kept frames must lie within 1-{args.frames} (first <= last)",
                )
            )
    if args.command in ("smoke", "fire", "styles"):
        checks.append((0 <= args.seed <= MAX_SEED, f"--seed must lie in [0, {MAX_SEED}], got {args.seed}"))
    if args.command == "smoke":
        validate_density_scale(args.density_scale, "--density-scale")
        checks += [
            (1 <= args.plumes <= 100000, f"--plumes must lie in [1, 100000], got {args.plumes}"),
            (
                args.crop == 0 or 4 <= args.crop <= args.res,
                f"--crop must be 0 (whole frames) or lie in [4, --res {args.res}], got {args.crop}",
            ),
            (
                1 <= args.crops_per_frame <= 1000,
                f"--crops-per-frame must lie in [1, 1000], got {args.crops_per_frame}",
            ),
            (1 <= args.directions <= 4096, f"--directions must lie in [1, 4096], got {args.directions}"),
        ]
    if args.command == "styles":
        low, high = STYLE_SIZE_RANGE
        checks.append((low <= args.size <= high, f"--size must lie in [{low}, {high}] pixels, got {args.size}"))
    if args.command == "mesh":
        checks += [
            (0 <= args.margin < 0.5, f"--margin must lie in [0, 0.5) of the box, got {args.margin}"),
            (1 <= args.supersample <= 8, f"--supersample must lie in [1, 8], got {args.supersample}"),
            (
                args.out.suffix.lower() in (".vol", ".npy"),
                f"--out must end in .vol or .npy, got {args.out}",
            ),
            (args.mesh is None or args.mesh.is_file(), f"--mesh {args.mesh} is not a file"),
            (
                not (args.out.exists() or args.out.is_symlink()),
                f"--out {args.out} already exists; mistyle-data mesh writes a new file: choose another name, "
                "or remove that one",
            ),
        ]
    for ok, message in checks:
        if not ok:
            raise ValueError(message + ".")
    if args.command != "mesh":
        check_dataset_out(args.out, LAYOUTS[args.command])


def check_dataset_out(out: Path, layout: re.Pattern) -> None:
    """``ValueError`` unless ``out`` is missing, or a folder holding only mistyle's files. A folder of an
    older mistyle's (no manifest; nothing but ``layout``'s files) gets its manifest here."""
    from ..ownership import adopt_older, check_replaceable, output_lock, read_manifest

    if out.exists() and not out.is_dir():
        raise ValueError(f"The output path {out} is a file; choose a folder for --out.")
    older = out.is_dir() and read_manifest(out) is None  # then its layout's files are not what is refused
    check_replaceable(out, "--out", also_ours=lambda name: older and layout.fullmatch(name) is not None)
    if older:
        with output_lock(out, wait=True):
            adopt_older(out, DATASET_KIND, layout)


def _command(args) -> int:
    """The chosen command's work; 2 for bad input, after one line on stderr. The files written into a
    dataset folder are recorded in its manifest as they end (``ownership.adding``)."""
    from ..ownership import adding

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
        from ..ownership import staged_directory
        from .tiny import make_tiny_dataset

        with staged_directory(args.out, DATASET_KIND) as staging:
            make_tiny_dataset(staging)
        print(f"wrote {args.out}")
        return 0
    if args.command == "styles":
        import json

        from ..files import atomic_write_bytes, write_png
        from .styles import offline_style_set, style_set_diversity

        styles = offline_style_set(size=args.size, seed=args.seed)
        names = [f"{name}.png" for name, _ in styles] + ["styles.json"]
        with adding(args.out, DATASET_KIND, names, rewritten=names):
            for name, image in styles:
                write_png(args.out / f"{name}.png", image, srgb=False)  # already sRGB-encoded
            summary = style_set_diversity(styles)
            atomic_write_bytes(args.out / "styles.json", (json.dumps(summary, indent=1) + "\n").encode())
        print(json.dumps(summary))
        return 0
    if args.command == "fire":
        from .generate import generate_fire

        first, last = keep = args.keep or (args.frames // 2 + 1, args.frames)
        names = [f"frame{frame:04d}.npz" for frame in range(first, last + 1)]
        try:
            with adding(args.out, DATASET_KIND, names):
                generate_fire(args.res, args.frames, keep, args.out, args.seed)
        except ValueError as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
        return 0

    from .generate import SmokeDatasetSpec, frame_path, generate_smoke

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

    index, count = args.shard
    manifest_name = "manifest.json" if count == 1 else f"manifest.shard-{index}-of-{count}.json"
    crops = range(spec.crops_per_frame) if spec.crop else [None]
    names = [
        frame_path(Path(), plume, frame, crop).as_posix()
        for plume in range(index, spec.plumes, count)
        for frame in range(first, last + 1)
        for crop in crops
    ]
    try:
        with adding(args.out, DATASET_KIND, names + [manifest_name], rewritten=[manifest_name]):
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
    from ..files import write_npy, write_vol
    from ..scenes.box import MediumBox
    from .mesh import icosphere, load_mesh, voxelize

    try:
        vertices, faces = load_mesh(args.mesh) if args.mesh else icosphere(4)
        density = voxelize(vertices, faces, args.res, args.margin, args.supersample)
        if args.out.suffix.lower() == ".vol":
            box = MediumBox(density.shape)
            write_vol(args.out, density, box.bbox_min, box.bbox_max)
        else:
            write_npy(args.out, density)
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}: density {density.shape} (Z, Y, X), {float((density > 0).mean()):.1%} occupied")
    return 0


if __name__ == "__main__":
    sys.exit(main())
