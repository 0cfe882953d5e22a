"""What stylizing a working copy costs the picture (#51): the default output on the full grid against
the default output stylized on a copy at half the grid's resolution (``--working-size``, ``mistyle.resample``),
on the real split.

A 512^3 frame is stylized on a 256^3 copy by default, and the full grid cannot be stylized here to
compare (``results/memory_trace/``: over 20 GB). The same halving on the real split's volumes, which
fit either way, measures what it costs: every pair rendered as users see it (``study.USER_SCORING``:
256^2, 64 spp, OIDN, the benchmark's three views) with the albedo of
- ``default``: the default output on the full grid (the working size above the grid's longest side);
- ``half``: the default output with the working size at half the grid's longest side (rounded up):
  network, colour match and look on the box-averaged copy, the albedo brought back to the full grid,
  the full density path traced;
- ``tuned_noise`` and ``uniform``: the benchmark's baselines, for scale.

The rule, written before the rows: the working copy keeps what users see if ``half``'s median RGB and
patch SWD are within 1.05x of ``default``'s and its structure distance is closer than tuned noise +
colour match's on at least as many pairs less one.

    .venv/bin/python experiments/working_size_study.py                 # about 20 min on this 2-core CPU
    .venv/bin/python experiments/working_size_study.py --report-only   # the table and sheet of the rows

Writes ``results/working_size_study/``: ``rows.jsonl`` (one line per pair and method; a re-run skips the
pairs it has), ``table.md``, ``sheet.jpg`` (each pair's first view: style, default, half, tuned noise).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

OUT = ROOT / "results" / "working_size_study"
METHODS = ("default", "half", "tuned_noise", "uniform")
SHEET_METHODS = ("default", "half", "tuned_noise")
TILE = 160


def albedo_of(method: str, context, density, style) -> np.ndarray:
    from mistyle.benchmark.methods import METHODS as REGISTERED

    if method == "half":
        half = math.ceil(max(density.shape) / 2)
        return context.pipeline(working_size=half).stylize(density, style).albedos[0]
    return REGISTERED[method].albedo(context, density, style)


def run(out: Path, densities: list[str]) -> None:
    from study import score_as_users_see

    from mistyle.benchmark.methods import Context
    from mistyle.benchmark.runner import metric_views
    from mistyle.benchmark.splits import split_density, split_pairs, split_styles
    from mistyle.files import load_style, write_png
    from mistyle.stylizer import Stylizer
    from mistyle.tone import display

    stylizer = Stylizer(None)
    context = Context(stylizer, metric_views(stylizer.config.render.camera_distance))
    styles = split_styles("real")
    rows_path = out / "rows.jsonl"
    done = set()
    if rows_path.exists():
        done = {(r["density"], r["style"], r["method"]) for r in map(json.loads, rows_path.read_text().splitlines())}
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout
    (out / "tiles").mkdir(parents=True, exist_ok=True)
    for spec, style_name in split_pairs("real", densities=densities):
        density = split_density(spec, None)
        style = load_style(styles[style_name]["path"])
        for method in METHODS:
            if (spec.name, style_name, method) in done:
                continue
            started = time.perf_counter()
            albedo = albedo_of(method, context, density, style)
            metrics, images = score_as_users_see(context, density, albedo, style)
            row = {
                "density": spec.name,
                "kind": spec.kind,
                "shape": list(density.shape),
                "style": style_name,
                "method": method,
                "metrics": metrics,
                "seconds": time.perf_counter() - started,
                "commit": commit.strip(),
                "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
                "load_1min": os.getloadavg()[0],
            }
            with rows_path.open("a") as stream:
                stream.write(json.dumps(row) + "\n")
            write_png(out / "tiles" / f"{spec.name}__{style_name}__{method}.png", display(images[0]), srgb=False)
            print(json.dumps({k: row[k] for k in ("density", "style", "method", "seconds")}), flush=True)


def table(rows: list[dict]) -> str:
    """Per density and over all: medians of RGB SWD, patch SWD, hue coverage and structure per method, the
    ratio of each median to ``default``'s, and on how many pairs each is closer in structure than tuned
    noise and than the uniform fill in both SWDs."""
    by = {(row["density"], row["style"], row["method"]): row["metrics"] for row in rows}
    groups = {
        density: [r for r in rows if r["density"] == density] for density in dict.fromkeys(r["density"] for r in rows)
    }
    groups["all real pairs"] = rows
    lines = []
    for name, mine in groups.items():
        pairs = sorted({(r["density"], r["style"]) for r in mine})
        lines += [
            f"### {name} ({len(pairs)} pairs)",
            "",
            "| method | RGB SWD | x default | patch SWD | x default | hue coverage | structure | "
            "structure < tuned noise | closer than uniform (both SWDs) |",
            "|---|---|---|---|---|---|---|---|---|",
        ]

        def median(method, key, pairs=pairs):
            values = [by[(d, s, method)][key] for d, s in pairs if (d, s, method) in by]
            return float(np.median(values)) if values else float("nan")

        for method in METHODS:
            have = [(d, s) for d, s in pairs if (d, s, method) in by]
            if not have:
                continue
            structure = [
                by[(d, s, method)]["structure"] < by[(d, s, "tuned_noise")]["structure"]
                for d, s in have
                if (d, s, "tuned_noise") in by
            ]
            uniform = [
                all(by[(d, s, method)][k] < by[(d, s, "uniform")][k] for k in ("rgb_swd", "patch_swd"))
                for d, s in have
                if (d, s, "uniform") in by
            ]
            lines.append(
                f"| {method} | {median(method, 'rgb_swd'):.4f} | "
                f"{median(method, 'rgb_swd') / median('default', 'rgb_swd'):.2f} | {median(method, 'patch_swd'):.4f} | "
                f"{median(method, 'patch_swd') / median('default', 'patch_swd'):.2f} | "
                f"{median(method, 'hue_coverage'):.2f} | {median(method, 'structure'):.3f} | "
                f"{sum(structure)}/{len(structure)} | {sum(uniform)}/{len(uniform)} |"
            )
        lines.append("")
    return "\n".join(lines)


def sheet(rows: list[dict], out: Path) -> None:
    """Every pair's first view: the style, then ``SHEET_METHODS``."""
    from study import contact_sheet

    from mistyle.benchmark.splits import split_styles

    styles = split_styles("real")
    pairs = sorted({(row["density"], row["style"]) for row in rows})
    lines = [
        (styles[style]["path"], [out / "tiles" / f"{density}__{style}__{method}.png" for method in SHEET_METHODS])
        for density, style in pairs
    ]
    captions = [f"{density} x {style}" for density, style in pairs]
    contact_sheet(lines, ["style", *SHEET_METHODS], out / "sheet.jpg", TILE, captions, quality=60)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument(
        "--densities", default="wdas_cloud,openvdb_smoke,usd_plume", help="comma-separated real densities"
    )
    parser.add_argument("--report-only", action="store_true")
    args = parser.parse_args(argv)
    if not args.report_only:
        run(args.out, args.densities.split(","))
    rows = [json.loads(line) for line in (args.out / "rows.jsonl").read_text().splitlines()]
    (args.out / "table.md").write_text(table(rows))
    sheet(rows, args.out)


if __name__ == "__main__":
    main()
