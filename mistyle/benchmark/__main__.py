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
    p.add_argument("--res", type=int, default=128, help="metric renders' side")
    p.add_argument("--spp", type=int, default=16, help="metric renders' paths per pixel")
    p.add_argument(
        "--optimise-factor",
        type=float,
        default=2.0,
        help="direct optimisation's steps as a multiple of the default refinement's",
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
    p.add_argument("--quick", action="store_true", help="the quick split at 32^2, 4 spp, 4+1 refinement steps")
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    out = args.out or (DEFAULT_OUT.with_name(DEFAULT_OUT.name + "-quick") if args.quick else DEFAULT_OUT)
    try:
        from ..stops import run_stoppable
        from .runner import report, run
        from .splits import split_pairs

        if args.report_only:
            if not (out / "rows.jsonl").exists():
                raise ValueError(f"{out / 'rows.jsonl'} does not exist; run the benchmark first.")
            print(report(out), end="")
            return 0
        split = "quick" if args.quick else args.split
        res, spp = (32, 4) if args.quick else (args.res, args.spp)
        for name, value, low in (("--res", res, 8), ("--spp", spp, 1)):
            if not low <= value <= 4096:
                raise ValueError(f"{name} must lie in [{low}, 4096], got {value}.")
        pairs = split_pairs(
            split,
            args.densities.split(",") if args.densities else None,
            args.styles.split(",") if args.styles else None,
        )

        def score() -> int:
            run(
                out,
                pairs,
                args.methods.split(","),
                res=res,
                spp=spp,
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

        kept = f"the rows scored so far are kept in {out / 'rows.jsonl'}; add --resume to go on from them"
        return run_stoppable(score, kept, in_process=argv is not None)
    except (ValueError, OSError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
