"""How close is a style to its own halves, in the benchmark's metrics? A scale for #48's distances.

The benchmark scores a render against a style picture with sliced Wasserstein distances between
their colours and 5x5 patches, hue coverage and a structure distance (``objective.metrics``). A
distance is only meaningful against a scale: here, the same metrics applied to the picture itself,
each half of it (left, right, top, bottom) scored against the whole exactly as a render's foreground
is (the half as one view, every pixel foreground). A half is another sample of the same painting: its
strokes, palette and patterns are the style's by construction, only its composition differs. A render
that is closer to the style than the style's own halves is as close as one part of the picture is to
the whole; below that, a distance rewards matching the whole picture's proportions, not looking more
like it.

    .venv/bin/python experiments/metric_floor.py             # seconds: the styles of the held-out and real splits

Writes ``results/metric_floor/``: ``rows.jsonl`` (one line per style: the four halves' metrics and
their mean) and ``table.md`` (each style's mean, then, for each method of the held-out and real
benchmark folders, its median and the number of pairs where it is closer than the style's halves).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

OUT = ROOT / "results" / "metric_floor"
BENCHMARKS = {
    "heldout": ROOT / "results" / "solid_texture_study" / "heldout" / "rows.jsonl",
    "real": ROOT / "results" / "benchmark-real" / "rows.jsonl",
}
METRICS = ("rgb_swd", "patch_swd", "hue_coverage", "structure")
HIGHER_IS_CLOSER = {"hue_coverage"}


def halves(style: np.ndarray) -> dict[str, np.ndarray]:
    height, width = style.shape[:2]
    return {
        "left": style[:, : width // 2],
        "right": style[:, width // 2 :],
        "top": style[: height // 2],
        "bottom": style[height // 2 :],
    }


def half_metrics(half: np.ndarray, style: np.ndarray) -> dict:
    """The benchmark's four metrics of display-space ``half`` (one view, all foreground) against ``style``."""
    from mistyle.objective.metrics import hue_coverage, patch_swd, sliced_wasserstein
    from mistyle.objective.structure import structure_distance

    return {
        "rgb_swd": sliced_wasserstein(half.reshape(-1, 3), style.reshape(-1, 3), order=1),
        "patch_swd": patch_swd([half], None, style),
        "hue_coverage": hue_coverage(half.reshape(-1, 3), style),
        "structure": structure_distance([half], None, style),
    }


def style_rows(splits: tuple[str, ...]) -> list[dict]:
    from mistyle.benchmark.splits import split_styles
    from mistyle.files import load_style

    rows = {}
    for split in splits:
        for name, spec in split_styles(split).items():
            if name in rows:
                rows[name]["splits"].append(split)
                continue
            style = load_style(spec["path"])
            parts = {part: half_metrics(image, style) for part, image in halves(style).items()}
            mean = {metric: float(np.mean([values[metric] for values in parts.values()])) for metric in METRICS}
            shape = list(style.shape[:2])
            rows[name] = {"style": name, "splits": [split], "shape": shape, "halves": parts, "mean": mean}
    return list(rows.values())


def latest_rows(path: Path) -> dict:
    """The newest row of each (method, density, style) at the user's scoring (256^2, denoised)."""
    rows = {}
    for line in path.read_text().splitlines():
        row = json.loads(line)
        settings = row.get("settings", {})
        if settings.get("res") == 256 and settings.get("denoise") == "oidn":
            rows[(row["method"], row["density"], row["style"])] = row
    return rows


def closer(value: float, floor: float, metric: str) -> bool:
    return value > floor if metric in HIGHER_IS_CLOSER else value < floor


def table(rows: list[dict]) -> str:
    floors = {row["style"]: row["mean"] for row in rows}
    lines = [
        "# Each style against its own halves, in the benchmark's metrics",
        "",
        "Made by `python experiments/metric_floor.py`. Each style's four halves (left, right, top, bottom)",
        "scored against the whole picture as the benchmark scores a render (the half one view, every pixel",
        "foreground); the mean of the four. Lower is closer, but for hue coverage.",
        "",
        "| style | RGB SWD | patch SWD | hue coverage | structure |",
        "|---|---|---|---|---|",
    ]
    for row in rows:
        lines.append(f"| {row['style']} | " + " | ".join(f"{row['mean'][m]:.4f}" for m in METRICS) + " |")
    lines.append(
        "| **median** | "
        + " | ".join(f"**{statistics.median(r['mean'][m] for r in rows):.4f}**" for m in METRICS)
        + " |"
    )
    for split, path in BENCHMARKS.items():
        if not path.is_file():
            continue
        bench = latest_rows(path)
        methods = sorted({key[0] for key in bench})
        lines += [
            "",
            f"## `{path.parent.relative_to(ROOT)}` ({split}): each method's median, and pairs closer than the halves",
            "",
            "| method | pairs | " + " | ".join(METRICS) + " |",
            "|---|---|" + "---|" * len(METRICS),
        ]
        for method in methods:
            members = [row for key, row in bench.items() if key[0] == method and row["style"] in floors]
            cells = []
            for metric in METRICS:
                values = [row[metric] for row in members]
                wins = sum(closer(row[metric], floors[row["style"]][metric], metric) for row in members)
                cells.append(f"{statistics.median(values):.4f} ({wins}/{len(members)})")
            lines.append(f"| {method} | {len(members)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    rows = style_rows(tuple(BENCHMARKS))
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "rows.jsonl", "w") as handle:
        for row in rows:
            handle.write(json.dumps(row) + "\n")
    (args.out / "table.md").write_text(table(rows))
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
