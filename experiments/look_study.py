"""What a look should hold (issue: looks, part 1): arms of ``look.LookSettings`` on held-out pairs.

Each arm fits a look on one held-out density with one held-out style (the single-frame case:
the frame is its own key frame), applies it, and scores the result as the benchmark does
(``study.score``: 3 metric views, 128^2, 16 spp), as ratios to the uniform baseline
next to the feed-forward network's (with its colour match). Fit and apply seconds are this
machine's, with whatever else runs.

    python experiments/look_study.py --arms head60,texture32 --densities pyroclastic64 --styles hokusai_great_wave
    python experiments/look_study.py --list                        # the arms and their settings

Rows: ``results/look_study/rows.jsonl`` (appended); the table the issue's closing note quotes is
``results/look_study/README.md``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

ARMS = {
    # the head (last kernel site and convolution) only, colour match fitted after the fit
    "head60": dict(texture_side=0, steps=60),
    "head120": dict(texture_side=0, steps=120),
    "head120_no_match": dict(texture_side=0, steps=120, colour_match="none"),
    "head120_patch0.2": dict(texture_side=0, steps=120, patch_weight=0.2),
    "head60_lr0.005": dict(texture_side=0, steps=60, lr=0.005),
    "head60_patch_only": dict(texture_side=0, steps=60, rgb_weight=0.0, patch_weight=1.0),
    "all_sites30_lr0.005": dict(texture_side=0, steps=30, tune_sites=(0, 1, 2, 3), lr=0.005),
    # fitted through the colour match (fitted first on the network's albedo)
    "head60_through_match": dict(texture_side=0, steps=60, colour_match="through"),
    "head60_through_match_lr0.001": dict(texture_side=0, steps=60, colour_match="through", lr=0.001),
    "head150_through_match": dict(texture_side=0, steps=150, colour_match="through"),
    # smooth-noise fields the head weighs
    "noise8_head60": dict(texture_side=0, steps=60, noise_channels=8),
    "noise8_head120": dict(texture_side=0, steps=120, noise_channels=8),
    "noise8_head60_lr0.05": dict(texture_side=0, steps=60, noise_channels=8, lr=0.05),
    # a texture over the box
    "texture64_head60": dict(texture_side=64, steps=60),
    "texture32_head60": dict(texture_side=32, steps=60),
    "texture64_head90_patch0.2": dict(texture_side=64, steps=90, patch_weight=0.2),
    "texture32_init0.3": dict(texture_init=0.3),
    "texture32_init1": dict(texture_init=1.0),
    "texture32_steps150": dict(steps=150),
    "default": dict(),
}


FROZEN_AT = "a2cd51f"
"""The last commit whose ``LookSettings`` has this study's arms (removed from the product on 2026-12-05): a
frozen study, run from a checkout of that commit."""


def main() -> None:
    from study import add_metric_arguments

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--arms", default="default")
    parser.add_argument("--densities", default="pyroclastic64,smoke64")
    parser.add_argument("--styles", default="hokusai_great_wave,texture_rusty_metal,van_gogh_starry_night")
    parser.add_argument("--out", type=Path, default=Path("results/look_study"))
    parser.add_argument("--list", action="store_true")
    add_metric_arguments(parser)
    args = parser.parse_args()
    from study import require_frozen_commit

    require_frozen_commit(__file__, FROZEN_AT)
    if args.list:
        for name, settings in ARMS.items():
            print(f"{name}: {settings}")
        return

    from study import metric_views, score, uniform_baseline

    from mistyle.benchmark.runner import code_commit
    from mistyle.data.heldout import HELD_OUT_DENSITIES, held_out_density, held_out_styles
    from mistyle.files import load_style
    from mistyle.look import LookSettings, fit_look
    from mistyle.stylizer import Stylizer

    stylizer = Stylizer()
    radiance = stylizer.config.render.radiance
    views = metric_views(stylizer.config.render.camera_distance)
    options = dict(res=args.res, spp=args.spp, density_scale=stylizer.density_scale, radiance=radiance)
    specs = {spec.name: spec for spec in HELD_OUT_DENSITIES}
    styles = held_out_styles()
    args.out.mkdir(parents=True, exist_ok=True)
    for density_name in args.densities.split(","):
        density = held_out_density(specs[density_name], args.cache)
        for style_name in args.styles.split(","):
            style = load_style(styles[style_name]["path"])
            uniform_albedo = uniform_baseline(
                density, style, views, density_scale=stylizer.density_scale, radiance=radiance
            )
            uniform = score(density, uniform_albedo, style, views, **options)[0]
            network = score(density, stylizer(density, style), style, views, **options)[0]
            for arm in args.arms.split(","):
                started = time.perf_counter()
                look = fit_look(stylizer, [density], style, settings=LookSettings(**ARMS[arm]))
                fitted = time.perf_counter() - started
                started = time.perf_counter()
                albedo = look.stylize(density)
                applied = time.perf_counter() - started
                metrics = score(density, albedo, style, views, **options)[0]
                row = {
                    "arm": arm,
                    "settings": ARMS[arm],
                    "density": density_name,
                    "style": style_name,
                    "fit_seconds": fitted,
                    "apply_seconds": applied,
                    **{f"{k}_x_uniform": metrics[k] / uniform[k] for k in ("rgb_swd", "patch_swd")},
                    **{f"network_{k}_x_uniform": network[k] / uniform[k] for k in ("rgb_swd", "patch_swd")},
                    "hue_coverage": metrics["hue_coverage"],
                    "commit": code_commit(),
                }
                print(json.dumps(row), flush=True)
                with open(args.out / "rows.jsonl", "a") as handle:
                    handle.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
