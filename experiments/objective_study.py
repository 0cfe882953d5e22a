"""Which objective, parametrisation and mask carry a style's hues and patterns (issue: style fidelity I).

Direct optimisation of an albedo grid through the fast layer (no network), from the must-beat
baseline's uniform albedo, one arm per choice with everything else fixed; each result is path traced
and scored with the fidelity benchmark's metrics (``study.score``), next to the baseline.

Arms (``name: objective / parametrisation / mask``):
  hist-sigmoid-fringe   the training objective (filter-bank histogram + RGB histogram) / sigmoid / radiance > 1e-3
  hist-log-fringe       the same, log-albedo
  hist-log-body         the same, loss only on the medium's body (white-albedo render > 0.5 on display)
  rgb-log-body          sliced Wasserstein of pixel colours only
  rgbpatch-log-body     + sliced Wasserstein of 5x5 pixel patches at scales 1, 1/2, 1/4
  rgbpatch-log-fringe   the same on every pixel that sees the medium

    python experiments/objective_study.py                       # 3 (density, style) pairs, 100 steps
    python experiments/objective_study.py --quick               # 1 pair, 10 steps, 2 arms
Writes JSON lines to stdout and, without --quick, docs/objective_study.md.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

ARMS = {
    "hist-sigmoid-fringe": ("histogram", "sigmoid", "fringe"),
    "hist-log-fringe": ("histogram", "log", "fringe"),
    "hist-log-body": ("histogram", "log", "body"),
    "rgb-log-body": ("rgb", "log", "body"),
    "rgbpatch-log-body": ("rgbpatch", "log", "body"),
    "rgbpatch-log-fringe": ("rgbpatch", "log", "fringe"),
}
# Part 2: render_final's refinement (``fit.refine_albedo``), from the network's albedo, with the
# chosen objective: how many fast-layer and path-traced steps, and the patch term's weight.
SCHEDULES = {
    "layer150-patch0": dict(layer_steps=150, path_steps=0, patch_weight=0.0),
    "layer150-patch0.05": dict(layer_steps=150, path_steps=0, patch_weight=0.05),
    "layer150-patch0.2": dict(layer_steps=150, path_steps=0, patch_weight=0.2),
    "layer120+path16-patch0.2": dict(layer_steps=120, path_steps=16, patch_weight=0.2),
    "layer120+path16-patch0.05": dict(layer_steps=120, path_steps=16, patch_weight=0.05),
    "path48-patch0.2": dict(layer_steps=0, path_steps=48, patch_weight=0.2),
}
PAIRS = [
    ("smoke64", "hokusai_great_wave"),
    ("smoke64", "kandinsky_composition_vii"),
    ("pyroclastic64", "van_gogh_starry_night"),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--res", type=int, default=128, help="metric renders")
    parser.add_argument("--spp", type=int, default=32)
    parser.add_argument("--fit-res", type=int, default=64)
    parser.add_argument("--arms", default=",".join(ARMS))
    parser.add_argument("--schedules", default=None, help="part 2: comma-separated SCHEDULES names, or all")
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--doc", default="results/objective_study/objective_study.md")
    args = parser.parse_args()
    pairs = PAIRS
    if args.quick:
        args.steps, args.res, args.spp, args.fit_res, pairs = 10, 48, 8, 48, PAIRS[:1]
        args.arms = "hist-log-fringe,rgbpatch-log-body"

    import torch
    from study import metric_views, score, uniform_baseline

    from mistyle.api import Stylizer
    from mistyle.data.heldout import HELD_OUT_DENSITIES, held_out_density, held_out_styles
    from mistyle.files import load_style
    from mistyle.fit import FitSettings, LayerViews, fit_albedo
    from mistyle.integrators import prepare_density
    from mistyle.model.features import square_style
    from mistyle.objective.style import SLICED_STYLE_SIZE, SlicedObjective, StyleObjective

    torch.manual_seed(0)
    stylizer = Stylizer()
    config = stylizer.config
    scale, radiance, distance = stylizer.density_scale, config.render.radiance, config.render.camera_distance
    views = metric_views(distance)
    specs = {spec.name: spec for spec in HELD_OUT_DENSITIES}
    styles = held_out_styles()
    rows = []
    for density_name, style_name in pairs:
        density = held_out_density(specs[density_name], "data/heldout")
        style = load_style(styles[style_name]["path"])
        prepared = prepare_density(density, scale)
        layer = LayerViews(prepared, args.fit_res, steps=config.render.steps, radiance=radiance)
        baseline = uniform_baseline(density, style, views, density_scale=scale, radiance=radiance)
        metrics, _ = score(
            density, baseline, style, views, res=args.res, spp=args.spp, density_scale=scale, radiance=radiance
        )
        row = {"density": density_name, "style": style_name, "arm": "uniform", **metrics}
        print(json.dumps(row), flush=True)
        rows.append(row)
        initial = torch.from_numpy(baseline).permute(3, 0, 1, 2)
        if args.schedules:
            from mistyle.fit import RefineSettings, refine_albedo

            network = stylizer(density, style)
            for name in list(SCHEDULES) if args.schedules == "all" else args.schedules.split(","):
                settings = RefineSettings(camera_distance=distance, tv_weight=config.loss.tv_weight, **SCHEDULES[name])
                albedo, seconds = refine_albedo(
                    density, scale, network, style, settings, radiance=radiance, prepared=prepared
                )
                metrics, _ = score(
                    density, albedo, style, views, res=args.res, spp=args.spp, density_scale=scale, radiance=radiance
                )
                row = {"density": density_name, "style": style_name, "arm": name, "seconds": seconds, **metrics}
                print(json.dumps(row), flush=True)
                rows.append(row)
            continue
        for arm in args.arms.split(","):
            loss, parametrisation, mask = ARMS[arm]
            objective = (
                StyleObjective(stylizer.extractor, config.loss.style, config.loss.rgb_weight)
                if loss == "histogram"
                else SlicedObjective(patch_weight=1.0 if loss == "rgbpatch" else 0.0)
            )
            # The histogram objective sees the style as the network does; the sliced one at SLICED_STYLE_SIZE.
            target = stylizer.style_tensor(style) if loss == "histogram" else square_style(style, SLICED_STYLE_SIZE)
            settings = FitSettings(
                steps=args.steps,
                lr=0.05,
                views_per_step=4,
                tv_weight=config.loss.tv_weight,
                camera_distance=distance,
                parametrisation=parametrisation,
            )
            fit = fit_albedo(
                layer, target, objective, initial, settings, masks=layer.body_masks if mask == "body" else None
            )
            albedo = np.ascontiguousarray(fit.albedo.permute(1, 2, 3, 0).numpy())
            metrics, _ = score(
                density, albedo, style, views, res=args.res, spp=args.spp, density_scale=scale, radiance=radiance
            )
            row = {"density": density_name, "style": style_name, "arm": arm, "seconds": fit.seconds, **metrics}
            print(json.dumps(row), flush=True)
            rows.append(row)
    if not args.quick:
        write_table(
            rows, Path(args.doc).with_name(Path(args.doc).stem + ("_refine" if args.schedules else "") + ".md"), args
        )


def write_table(rows, path: Path, args) -> None:
    arms = list(dict.fromkeys(row["arm"] for row in rows))
    lines = [
        "| arm | RGB SWD (x baseline) | patch SWD (x baseline) | hue coverage | seconds |",
        "|---|---|---|---|---|",
    ]
    baseline = {(r["density"], r["style"]): r for r in rows if r["arm"] == "uniform"}
    for arm in arms:
        mine = [r for r in rows if r["arm"] == arm]
        ratio = lambda key: np.median([r[key] / baseline[(r["density"], r["style"])][key] for r in mine])  # noqa: E731
        lines.append(
            f"| {arm} | {np.median([r['rgb_swd'] for r in mine]):.4f} ({ratio('rgb_swd'):.2f}x) | "
            f"{np.median([r['patch_swd'] for r in mine]):.4f} ({ratio('patch_swd'):.2f}x) | "
            f"{np.median([r['hue_coverage'] for r in mine]):.2f} | "
            f"{np.median([r.get('seconds', 0.0) for r in mine]):.0f} |"
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    (path.with_suffix(".jsonl")).write_text("".join(json.dumps(r) + "\n" for r in rows))
    path.with_name(path.stem + "_table.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
