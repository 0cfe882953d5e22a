"""How far the structure distance moves with the seeds alone: a look's fit and the path tracer (#48).

A study arm is chosen when its median structure distance is 0.02 below the default's; per pair the
default's structure moved by up to 0.08 between two versions of the code that changed its albedo by
rounding (``results/validation-dense/README.md``). This measures the spread a seed alone gives, on
the held-out pairs of one density, scored as ``mistyle-bench`` scores (256^2, 64 spp, OIDN, its three
views): the default output with its look's seed 0 and 1 (``LookSettings.seed``: views, objective,
colour match), each path traced with seed 0; the seed-0 look path traced with seed 1; and tuned noise +
colour match path traced with seeds 0 and 1.

    .venv/bin/python experiments/structure_seed_spread.py --density pyroclastic64   # about 12 min

Rows: ``results/structure_seed_spread/rows.jsonl`` (one per pair: every structure distance).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
OUT = ROOT / "results" / "structure_seed_spread"


def structure(context, density, albedo, style, seed: int) -> float:
    """The benchmark's structure distance of ``albedo`` path traced with ``seed`` (``runner.score``)."""
    from study import score_as_users_see

    metrics, _ = score_as_users_see(context, density, albedo, style, seed)
    return float(metrics["structure"])


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--density", default="pyroclastic64")
    parser.add_argument("--split", default="heldout")
    args = parser.parse_args(argv)
    from mistyle.benchmark.methods import Context, tuned_noise
    from mistyle.benchmark.runner import metric_views
    from mistyle.benchmark.splits import split_density, split_pairs, split_styles
    from mistyle.files import load_style
    from mistyle.look import LookSettings
    from mistyle.stylizer import Stylizer

    stylizer = Stylizer(None)
    context = Context(stylizer, metric_views(stylizer.config.render.camera_distance))
    pipeline = context.pipeline(refine_steps=0, refine_path_steps=0)
    styles = split_styles(args.split)
    OUT.mkdir(parents=True, exist_ok=True)
    rows = []
    for spec, name in split_pairs(args.split, [args.density]):
        density, style = split_density(spec), load_style(styles[name]["path"])
        looks = [pipeline.fit_look(density, style, look_settings=LookSettings(seed=seed)) for seed in (0, 1)]
        albedos = [look.stylize(density) for look in looks]
        noise = context.stylizer.match_colours([tuned_noise(density.shape, 0)], [density], style)[0]
        row = {
            "density": spec.name,
            "style": name,
            "default_fit0_render0": structure(context, density, albedos[0], style, 0),
            "default_fit1_render0": structure(context, density, albedos[1], style, 0),
            "default_fit0_render1": structure(context, density, albedos[0], style, 1),
            "tuned_render0": structure(context, density, noise, style, 0),
            "tuned_render1": structure(context, density, noise, style, 1),
        }
        rows.append(row)
        print(json.dumps(row), flush=True)
        (OUT / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    base = np.array([r["default_fit0_render0"] for r in rows])
    for key in ("default_fit1_render0", "default_fit0_render1"):
        moved = np.abs(np.array([r[key] for r in rows]) - base)
        print(f"{key}: |change| median {np.median(moved):.3f}, max {moved.max():.3f}")
    tuned = np.abs(np.array([r["tuned_render1"] - r["tuned_render0"] for r in rows]))
    print(f"tuned noise, render seed: |change| median {np.median(tuned):.3f}, max {tuned.max():.3f}")
    for fit, render in ((0, 0), (1, 0), (0, 1)):
        closer = sum(r[f"default_fit{fit}_render{render}"] < r[f"tuned_render{render}"] for r in rows)
        print(f"fit seed {fit}, render seed {render}: closer than tuned noise on {closer} of {len(rows)}")


if __name__ == "__main__":
    main()
