"""A look's benchmark rows under other fit settings (or code) against a reference, on every pair both have.

Each input is the rows of one method (``--method``, default ``look``) of one ``mistyle-bench`` run: a
``rows.jsonl`` (or that method's lines of such a file), or the command's printed output (``look  density
style  RGB x patch y hue z structure w``: four digits for the SWDs, three for the structure distance).
The table gives per metric the geometric mean and median of per-pair ratios to the reference (lower
is better) and the pairs where the candidate is lower.

    python experiments/look_benchmark_compare.py --reference results/look_speed/benchmark/look_90_independent.jsonl \\
        --candidate 60_stratified=results/look_speed/benchmark/look_60_stratified.log \\
        --candidate 90_stratified=results/benchmark/rows.jsonl --out results/look_speed/benchmark/table.md
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np

METRICS = ("rgb_swd", "patch_swd", "structure")
PRINTED = re.compile(r"^(\S+)\s+(\S+)\s+(\S+)\s+RGB (\S+) patch (\S+) hue \S+ structure (\S+)")


def look_rows(path: Path, method: str = "look") -> dict[tuple[str, str], dict]:
    rows = {}
    for line in path.read_text().splitlines():
        if line.startswith("{"):
            row = json.loads(line)
            if row["method"] == method:
                rows[(row["density"], row["style"])] = {metric: row[metric] for metric in METRICS}
        elif (match := PRINTED.match(line)) and match.group(1) == method:
            _, density, style, *values = match.groups()
            rows[(density, style)] = dict(zip(METRICS, map(float, values)))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--reference", type=Path, required=True)
    parser.add_argument("--candidate", action="append", required=True, help="NAME=PATH")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--method", default="look", help="the benchmark method whose rows are compared")
    args = parser.parse_args()
    reference = look_rows(args.reference, args.method)
    lines = [
        f"`{args.method}` rows against `{args.reference}` ({len(reference)} pairs): per-pair "
        "ratios (lower is better), geometric mean / median, and the pairs where the candidate is lower.",
        "",
        "| candidate | pairs | " + " | ".join(f"{metric} (geo. mean / median / lower)" for metric in METRICS) + " |",
        "|---|---|" + "---|" * len(METRICS),
    ]
    for name, path in (item.split("=", 1) for item in args.candidate):
        rows = look_rows(Path(path), args.method)
        pairs = sorted(set(rows) & set(reference))
        cells = []
        for metric in METRICS:
            ratios = np.array([rows[pair][metric] / reference[pair][metric] for pair in pairs])
            cells.append(
                f"{np.exp(np.log(ratios).mean()):.3f} / {np.median(ratios):.3f} / {(ratios < 1).sum()} of {len(pairs)}"
            )
        lines.append(f"| {name} (`{path}`) | {len(pairs)} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "`python experiments/look_benchmark_compare.py "
        + " ".join(
            [f"--reference {args.reference}", f"--method {args.method}"]
            + [f"--candidate {item}" for item in args.candidate]
            + [f"--out {args.out}"]
        )
        + "`",
        "",
    ]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
