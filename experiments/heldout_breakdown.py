"""A benchmark's rows broken down by kind of style (painting, photograph, texture) and by density.

The benchmark's table gives medians over all held-out pairs. When a change wins on the validation
split (paintings on one smoke density) and not on the held-out split, this says where it lost: the
medians of per-pair ratios to ``smooth_noise`` and to ``tuned_noise`` for each group of pairs.

    python experiments/heldout_breakdown.py results/noise_rgb/benchmark --out results/noise_rgb/breakdown.md
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from mistyle.benchmark.runner import read_rows


def style_kind(name: str) -> str:
    """The held-out styles' names say their kind: ``photo_*``, ``texture_*``, otherwise a painting."""
    return "photograph" if name.startswith("photo_") else "texture" if name.startswith("texture_") else "painting"


def breakdown(rows, methods: list[str]) -> str:
    table = {(row.method, row.density, row.style): row for row in rows}
    pairs = sorted({(row.density, row.style) for row in rows if row.method == "smooth_noise"})
    groups = {"all": pairs}
    for kind in ("painting", "photograph", "texture"):
        groups[kind] = [pair for pair in pairs if style_kind(pair[1]) == kind]
    for density in dict.fromkeys(density for density, _ in pairs):
        groups[density] = [pair for pair in pairs if pair[0] == density]
    lines = [
        "Medians of per-pair ratios (lower is better) of RGB / patch SWD to `smooth_noise` and to `tuned_noise`, "
        "by group of held-out pairs.",
        "",
        "| method | group | pairs | RGB x noise | patch x noise | RGB x tuned | patch x tuned |",
        "|---|---|---|---|---|---|---|",
    ]
    for method in methods:
        for group, members in groups.items():
            members = [pair for pair in members if (method, *pair) in table]
            if not members:
                continue
            cells = []
            for baseline in ("smooth_noise", "tuned_noise"):
                for key in ("rgb_swd", "patch_swd"):
                    ratios = [
                        getattr(table[(method, *pair)], key) / getattr(table[(baseline, *pair)], key)
                        for pair in members
                        if (baseline, *pair) in table
                    ]
                    cells.append(f"{np.median(ratios):.3f}" if ratios else "n/a")
            lines.append(f"| {method} | {group} | {len(members)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("folder", type=Path, help="a benchmark's results folder (its rows.jsonl)")
    parser.add_argument("--methods", default="", help="comma-separated (default: every method but the baselines)")
    parser.add_argument("--out", type=Path, help="write the table here too")
    args = parser.parse_args(argv)
    rows = read_rows(args.folder / "rows.jsonl")
    baselines = {"smooth_noise", "tuned_noise", "uniform"}
    methods = args.methods.split(",") if args.methods else [m for m in dict.fromkeys(r.method for r in rows)]
    methods = [m for m in methods if args.methods or m not in baselines]
    text = breakdown(rows, methods)
    if args.out:
        args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
