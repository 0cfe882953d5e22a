"""Does the colour match's feedback step help? (#13; ``mistyle.colour_match``, step 4)

On each validation pair (``train.dataset.validation_paintings`` x ``val_smoke64``, never the
benchmark's held-out pairs) the bundled network's albedo is colour matched with and without the
feedback step (one path-traced render of the matched albedo from ``FEEDBACK_VIEWS`` views around the
orbit, whose foreground colours a second transport carries onto the style's), and each arm is scored
like the benchmark (``study.score``), pooled over the metric views and view by view.

The references, direct optimisation and the uniform baseline, are not rerun: their scores are read
from ``gap_decomposition.py``'s rows (``--reference``), which scored the same pairs with the same
metric renders (``--res``, ``--spp`` and seeds must match; the script refuses a reference without
the pair). Each arm's seconds are the fit and the application of the match, network excluded.

Writes ``<out>.jsonl`` (a line per pair), ``<out>.md`` (medians over pairs: RGB SWD as a multiple of
optimisation's, pooled and per view; patch SWD x uniform; hue coverage; seconds) and ``<out>.jpg``
(style | network | no feedback | feedback, the held-out view, first ``SHEET_PAIRS`` pairs).

    python experiments/colour_match_feedback.py            # 13 pairs: about 8 min on 2 cores
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from study import add_metric_arguments

ARMS = {"no feedback": False, "feedback": True}
SHEET_PAIRS = 4


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="results/colour_match_feedback/colour_match_feedback")
    parser.add_argument(
        "--reference",
        default="results/gap_decomposition/gap_decomposition.jsonl",
        help="gap_decomposition.py's rows: the optimised and uniform scores of each pair",
    )
    add_metric_arguments(parser)
    args = parser.parse_args()

    from study import metric_views, score

    from mistyle.api import Stylizer
    from mistyle.colour_match import fit_colour_match
    from mistyle.data.heldout import VALIDATION_DENSITIES, held_out_density
    from mistyle.files import load_style
    from mistyle.objective.metrics import style_fidelity
    from mistyle.pages import EXPERIMENTS_TITLE, write_grid, write_index
    from mistyle.tone import display
    from mistyle.train.dataset import validation_paintings

    lines = Path(args.reference).read_text().splitlines()
    references = {(r["density"], r["style"]): r for r in map(json.loads, lines)}
    stylizer = Stylizer()
    render = stylizer.config.render
    settings = dict(
        density_scale=stylizer.density_scale, radiance=render.radiance, camera_distance=render.camera_distance
    )
    views = metric_views(render.camera_distance)
    out = Path(args.out)
    rows, sheet = [], []
    for spec in VALIDATION_DENSITIES:
        density = held_out_density(spec, args.cache)
        for painting in validation_paintings():
            reference = references.get((spec.name, painting.stem))
            if reference is None:
                raise SystemExit(
                    f"{args.reference} has no row for {spec.name} x {painting.stem}: run gap_decomposition.py first."
                )
            style = load_style(painting)
            network = stylizer(density, style, match_colours=False)
            row = {
                "density": spec.name,
                "style": painting.stem,
                "optimised": reference["optimised"],
                "uniform": reference["uniform"],
            }
            tiles = [(style, painting.stem[:18])]
            for arm, feedback in ARMS.items():
                started = time.perf_counter()
                match = fit_colour_match(network, density, style, feedback=feedback, **settings)
                albedo = match.apply(network, density)
                seconds = time.perf_counter() - started
                row[arm], images = score(
                    density,
                    albedo,
                    style,
                    views,
                    res=args.res,
                    spp=args.spp,
                    density_scale=stylizer.density_scale,
                    radiance=render.radiance,
                )
                row[arm]["rgb_swd_per_view"] = float(
                    np.mean([style_fidelity(image[None], style)["rgb_swd"] for image in images])
                )
                row[arm]["seconds"] = seconds
                if arm == "no feedback" and len(sheet) < SHEET_PAIRS:
                    _, network_images = score(
                        density,
                        network,
                        style,
                        views[:1],
                        res=args.res,
                        spp=args.spp,
                        density_scale=stylizer.density_scale,
                        radiance=render.radiance,
                    )
                    tiles.append((display(network_images[0]), "network"))
                tiles.append((display(images[0]), arm))
            if len(sheet) < SHEET_PAIRS:
                sheet.append(tiles)
            rows.append(row)
            print(json.dumps(row), flush=True)
    out.with_suffix(".jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    text = table(rows)
    out.with_suffix(".md").write_text(text)
    print(text)
    write_grid(out.with_suffix(".jpg"), sheet)
    write_index(out.parent, EXPERIMENTS_TITLE)


def table(rows: list[dict]) -> str:
    """Medians over pairs of each arm's RGB SWD x optimised (pooled, per view), patch SWD x uniform, hue
    coverage and seconds, and on how many pairs the feedback lowers the pooled RGB SWD."""
    lines = [
        f"Medians over {len(rows)} validation pairs (lower is better, hue coverage higher is better).",
        "",
        "| arm | RGB SWD x optimised | per view | patch SWD x uniform | hue coverage | seconds |",
        "|---|---|---|---|---|---|",
    ]
    for arm in ARMS:

        def median(value):
            return float(np.median([value(r) for r in rows]))

        lines.append(
            f"| {arm} | {median(lambda r: r[arm]['rgb_swd'] / r['optimised']['rgb_swd']):.3f} | "
            f"{median(lambda r: r[arm]['rgb_swd_per_view'] / r['optimised']['rgb_swd_per_view']):.3f} | "
            f"{median(lambda r: r[arm]['patch_swd'] / r['uniform']['patch_swd']):.3f} | "
            f"{median(lambda r: r[arm]['hue_coverage']):.3f} | {median(lambda r: r[arm]['seconds']):.2f} |"
        )
    better = sum(r["feedback"]["rgb_swd"] < r["no feedback"]["rgb_swd"] for r in rows)
    lines += ["", f"The feedback lowers the pooled RGB SWD on {better} of the {len(rows)} pairs."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
