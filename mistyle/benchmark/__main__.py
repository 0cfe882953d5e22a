"""``mistyle-bench`` (``python -m mistyle.benchmark``): the style-fidelity benchmark (see ``mistyle.benchmark``).

mistyle-bench --quick                                   # a minute: 1 small density, 2 styles, 4+1 steps
mistyle-bench                                           # the held-out split, every method (hours on 2 cores)
mistyle-bench --methods network,density_ramp,smooth_noise,uniform --resume
mistyle-bench --split heldout128 --methods network,uniform
mistyle-bench --split validation --methods network --checkpoint runs/x/steps/step_000600.pt --out runs/x/validation
mistyle-bench --report-only                             # table.md, sheet.jpg, index.html from rows.jsonl
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

DEFAULT_OUT = Path("results") / "benchmark"
MAX_OPTIMISE_FACTOR = 100.0


def parser() -> argparse.ArgumentParser:
    from .methods import METHODS
    from .splits import SPLITS

    p = argparse.ArgumentParser(
        prog="mistyle-bench", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--split", default="heldout", choices=list(SPLITS), help="which pairs (default: heldout)")
    p.add_argument("--densities", default=None, help="comma-separated density names of the split (default: all)")
    p.add_argument("--styles", default=None, help="comma-separated style names of the split (default: all)")
    p.add_argument("--methods", default=",".join(METHODS), help=f"comma-separated, of {', '.join(METHODS)}")
    p.add_argument(
        "--res", type=int, default=None, help="metric renders' side (default 256, as mistyle-render; 32 with --quick)"
    )
    p.add_argument(
        "--spp",
        type=int,
        default=None,
        help="metric renders' paths per pixel (default 64, as mistyle-render; 4 with --quick)",
    )
    p.add_argument(
        "--denoise",
        choices=["oidn", "none"],
        default=None,
        help="denoise the metric renders as mistyle-render does (default oidn; none with --quick)",
    )
    p.add_argument(
        "--optimise-factor",
        type=float,
        default=2.0,
        help=f"direct optimisation's steps as a multiple of the default refinement's, in (0, {MAX_OPTIMISE_FACTOR:g}]",
    )
    p.add_argument("--checkpoint", type=Path, default=None, help="SKPN checkpoint (default: the bundled one)")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help=f"results folder (default: {DEFAULT_OUT}; {DEFAULT_OUT}-quick with --quick)",
    )
    p.add_argument("--cache", type=Path, default=Path("data") / "heldout", help="where held-out densities are cached")
    p.add_argument("--resume", action="store_true", help="skip rows already in rows.jsonl (same settings)")
    p.add_argument("--report-only", action="store_true", help="rewrite the report from rows.jsonl")
    p.add_argument(
        "--quick", action="store_true", help="the quick split at 32^2, 4 spp (unless given), 4+1 refinement steps"
    )
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    out = args.out or (DEFAULT_OUT.with_name(DEFAULT_OUT.name + "-quick") if args.quick else DEFAULT_OUT)
    try:
        from ..stops import run_stoppable
        from .runner import REPORT_FILES, ROWS_FILE, check_methods, folder_files, owned_folder, report, run
        from .splits import split_pairs

        if out.exists() and not out.is_dir():
            raise ValueError(f"The output path {out} is a file; choose a folder for --out.")
        if args.report_only:
            if not (out / ROWS_FILE).exists():
                raise ValueError(f"{out / ROWS_FILE} does not exist; run the benchmark first.")
            with owned_folder(out, list(REPORT_FILES)):
                print(report(out), end="")
            return 0
        split = "quick" if args.quick else args.split
        res, spp, denoise = check_settings(args)
        for option, value in (("--densities", args.densities), ("--styles", args.styles)):
            if value is not None and not value.strip(", "):
                raise ValueError(f"{option} names none; give comma-separated names, or leave {option} out for all.")
        pairs = split_pairs(
            split,
            args.densities.split(",") if args.densities else None,
            args.styles.split(",") if args.styles else None,
        )
        methods = args.methods.split(",")
        check_methods(methods)

        def score() -> int:
            with owned_folder(out, folder_files(pairs, methods)):
                run(
                    out,
                    pairs,
                    methods,
                    res=res,
                    spp=spp,
                    denoise=denoise,
                    quick=args.quick,
                    resume=args.resume,
                    checkpoint=args.checkpoint,
                    optimise_factor=args.optimise_factor,
                    cache=args.cache,
                    split=split,
                )
            print((out / "table.md").read_text(), end="")
            print(f"wrote {out}/: rows.jsonl, table.md, sheet.jpg, index.html")
            return 0

        kept = f"the rows scored so far are kept in {out / ROWS_FILE}; add --resume to go on from them"
        return run_stoppable(score, kept, in_process=argv is not None)
    except (ValueError, OSError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2


def check_settings(args) -> tuple[int, int, str]:
    """``(res, spp, denoise)`` of the metric renders: by default what ``mistyle-render`` shows a user
    (256^2, 64 spp, denoised), ``--quick``'s unless given; every setting checked first."""
    import math

    from ..denoise import oidn_missing

    res = args.res if args.res is not None else (32 if args.quick else 256)
    spp = args.spp if args.spp is not None else (4 if args.quick else 64)
    denoise = args.denoise or ("none" if args.quick else "oidn")
    if denoise == "oidn" and oidn_missing() is not None:
        raise ValueError(oidn_missing().replace("--denoise none", "mistyle-bench --denoise none"))
    for name, value, low in (("--res", res, 8), ("--spp", spp, 1)):
        if not low <= value <= 4096:
            raise ValueError(f"{name} must lie in [{low}, 4096], got {value}.")
    factor = args.optimise_factor
    if not (math.isfinite(factor) and 0 < factor <= MAX_OPTIMISE_FACTOR):
        raise ValueError(f"--optimise-factor must lie in (0, {MAX_OPTIMISE_FACTOR:g}], got {factor:g}.")
    return res, spp, denoise


if __name__ == "__main__":
    sys.exit(main())
