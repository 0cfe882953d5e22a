"""On the real split, do the colour and patch distances measure the style, or how bright the medium is? (#48)

A thin smoke under the benchmark's light renders darker than most pictures whatever its albedo:
light it scatters is bounded by its optical depth. Where the picture is brighter than any albedo can
make the medium, a sliced Wasserstein distance between their colours favours the brightest albedo,
whatever its hue. This study scores, on the real split's pairs, the default output, the uniform
fill, a white medium (albedo 1 everywhere: no style at all) and tuned noise + colour match, each path
traced as users see it (``study.USER_SCORING``: 256^2, 64 spp, OIDN) and scored twice: as rendered
(the benchmark's scoring) and at the exposure that gives the foreground the style's mean display
value (``objective.metrics.exposure_matched_fidelity``: one factor on the linear renders of a
pair's three views, the foreground as rendered).

The rule, written before the rows: the as-rendered distances measure brightness rather than style on
a density if the white medium, which carries nothing of any style, is closer to the styles than the
default output in RGB SWD on most of its pairs. Then that density's as-rendered comparison with the
uniform fill says nothing about style, and the exposure-matched one is reported beside it.

    .venv/bin/python experiments/exposure_study.py                 # about 25 min on this 2-core CPU
    .venv/bin/python experiments/exposure_study.py --report-only   # the table and sheet of the rows

Writes ``results/exposure_study/``: ``rows.jsonl`` (one line per pair and method, both scorings; a
re-run skips the pairs it has), ``table.md``, ``sheet.jpg`` (openvdb_smoke's pairs, first view: style,
then each method as rendered, then each at the matched exposure) and the tiles it is made of.
"""

from __future__ import annotations

import argparse
import json
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

OUT = ROOT / "results" / "exposure_study"
METHODS = ("default", "uniform", "white", "tuned_noise")
SHEET_DENSITY = "openvdb_smoke"
TILE = 256


def albedo_of(method: str, context, density, style) -> np.ndarray:
    from mistyle.benchmark.methods import METHODS as REGISTERED

    if method == "white":
        return np.ones(density.shape + (3,), np.float32)
    return REGISTERED[method].albedo(context, density, style)


def tile_of(image: np.ndarray, path: Path) -> None:
    from mistyle.files import write_png
    from mistyle.tone import display

    path.parent.mkdir(parents=True, exist_ok=True)
    write_png(path, display(image), srgb=False)


def run(out: Path, densities: list[str] | None) -> None:
    from study import score_as_users_see

    from mistyle.benchmark.methods import Context
    from mistyle.benchmark.runner import metric_views
    from mistyle.benchmark.splits import split_density, split_pairs, split_styles
    from mistyle.files import load_style
    from mistyle.objective.metrics import exposure_matched_fidelity
    from mistyle.stylizer import Stylizer

    stylizer = Stylizer(None)
    context = Context(stylizer, metric_views(stylizer.config.render.camera_distance))
    styles = split_styles("real")
    rows_path = out / "rows.jsonl"
    done = set()
    if rows_path.exists():
        done = {(r["density"], r["style"], r["method"]) for r in map(json.loads, rows_path.read_text().splitlines())}
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout
    out.mkdir(parents=True, exist_ok=True)
    for spec, style_name in split_pairs("real", densities=densities):
        density = split_density(spec, None)
        style = load_style(styles[style_name]["path"])
        for method in METHODS:
            if (spec.name, style_name, method) in done:
                continue
            started = time.perf_counter()
            albedo = albedo_of(method, context, density, style)
            rendered, images = score_as_users_see(context, density, albedo, style)
            matched, exposure = exposure_matched_fidelity(images, style)
            row = {
                "density": spec.name,
                "kind": spec.kind,
                "style": style_name,
                "method": method,
                "as_rendered": rendered,
                "exposure_matched": matched,
                "exposure": exposure,
                "seconds": time.perf_counter() - started,
                "commit": commit.strip(),
                "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
                "load_1min": os.getloadavg()[0],
            }
            with rows_path.open("a") as stream:
                stream.write(json.dumps(row) + "\n")
            tile_of(images[0], out / "tiles" / f"{spec.name}__{style_name}__{method}.png")
            tile_of(images[0] * exposure, out / "tiles" / f"{spec.name}__{style_name}__{method}__matched.png")
            print(json.dumps({k: row[k] for k in ("density", "style", "method", "exposure", "seconds")}), flush=True)


def table(rows: list[dict]) -> str:
    """Per density and scoring: medians of RGB and patch SWD and hue coverage per method, and on how many
    pairs each method is closer than the uniform fill in both SWDs and than the white medium in RGB."""
    lines = []
    for density in dict.fromkeys(row["density"] for row in rows):
        mine = [row for row in rows if row["density"] == density]
        by = {(row["style"], row["method"]): row for row in mine}
        pairs = sorted({row["style"] for row in mine})
        lines += [
            f"### {density} ({mine[0]['kind']}, {len(pairs)} pairs)",
            "",
            "| method | scoring | RGB SWD | patch SWD | hue coverage | closer than uniform (both SWDs) | "
            "closer than white (RGB) | exposure |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for method in METHODS:
            for scoring in ("as_rendered", "exposure_matched"):
                have = [by[(s, method)] for s in pairs if (s, method) in by]
                if not have:
                    continue

                def median(key, have=have, scoring=scoring):
                    return float(np.median([row[scoring][key] for row in have]))

                def beats(other, keys, have=have, scoring=scoring):
                    won = [
                        all(row[scoring][k] < by[(row["style"], other)][scoring][k] for k in keys)
                        for row in have
                        if (row["style"], other) in by
                    ]
                    return f"{sum(won)}/{len(won)}"

                exposure = float(np.median([row["exposure"] for row in have]))
                lines.append(
                    f"| {method} | {scoring.replace('_', ' ')} | {median('rgb_swd'):.4f} | {median('patch_swd'):.4f} | "
                    f"{median('hue_coverage'):.2f} | {beats('uniform', ('rgb_swd', 'patch_swd'))} | "
                    f"{beats('white', ('rgb_swd',))} | {exposure:.2f} |"
                )
        lines.append("")
    return "\n".join(lines)


def sheet(rows: list[dict], out: Path) -> None:
    """``SHEET_DENSITY``'s pairs: the style, each method as rendered, then each at the matched exposure."""
    from study import contact_sheet

    from mistyle.benchmark.splits import split_styles

    styles = split_styles("real")
    pairs = sorted({row["style"] for row in rows if row["density"] == SHEET_DENSITY})
    columns = ["style"] + list(METHODS) + [f"{m} (matched)" for m in METHODS]
    lines = [
        (
            styles[style_name]["path"],
            [
                out / "tiles" / f"{SHEET_DENSITY}__{style_name}__{method}{suffix}.png"
                for suffix in ("", "__matched")
                for method in METHODS
            ],
        )
        for style_name in pairs
    ]
    contact_sheet(lines, columns, out / "sheet.jpg", TILE)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument(
        "--densities",
        default="openvdb_smoke,usd_plume,wdas_cloud",
        help="comma-separated real densities (the README's)",
    )
    parser.add_argument("--report-only", action="store_true")
    args = parser.parse_args(argv)
    if not args.report_only:
        run(args.out, args.densities.split(","))
    rows = [json.loads(line) for line in (args.out / "rows.jsonl").read_text().splitlines()]
    (args.out / "table.md").write_text(table(rows))
    sheet(rows, args.out)
    print(table(rows))


if __name__ == "__main__":
    main()
