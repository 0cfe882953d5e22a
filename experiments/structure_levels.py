"""The structure distance split by pyramid level and term: where a method's render loses the style's structure.

For each held-out pair given, each method's albedo is path traced as the benchmark scores it (256^2,
64 spp, OIDN, its three views) and ``objective.structure``'s distance is printed per level: the
gradient-magnitude term, the orientation term (each weighted over the three channels as the metric
weights them) and the ratio of the render's mean luminance-gradient magnitude to the style's.

    .venv/bin/python experiments/structure_levels.py --density pyroclastic64 \
        --styles hokusai_great_wave,van_gogh_starry_night --methods default,solid_texture,tuned_noise
    .venv/bin/python experiments/structure_levels.py --density pyroclastic64 --styles hokusai_great_wave \
        --arms look_structure_study --methods default,look_before,tuned_noise     # a study's arms too
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def level_terms(images: list, style: np.ndarray) -> list:
    """Per level: ``(magnitude term, orientation term, luminance-gradient ratio)``, or None where the
    level has too few positions; the terms weighted over channels as ``statistics_distance`` weighs them."""
    from mistyle.objective import structure
    from mistyle.objective.metrics import display, foreground_mask

    ours = structure.structure_statistics([display(i) for i in images], [foreground_mask(i) for i in images])
    theirs = structure.structure_statistics([style], None)
    weights = np.asarray(structure.CHANNEL_WEIGHTS) / np.sum(structure.CHANNEL_WEIGHTS)
    terms = []
    for mine, reference in zip(ours, theirs):
        if mine is None or reference is None:
            terms.append(None)
            continue
        (q_ours, h_ours), (q_style, h_style) = mine, reference
        magnitude = np.abs(q_ours - q_style).mean(axis=1) / (q_style[0].mean() + 1e-3)
        energy = q_style.mean(axis=1) / max(q_style.mean(axis=1).max(), 1e-12)
        orientation = np.abs(h_ours - h_style).sum(axis=1) * energy
        ratio = q_ours[0].mean() / max(q_style[0].mean(), 1e-9)
        terms.append((float(weights @ magnitude), float(weights @ orientation), float(ratio)))
    return terms


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", default="heldout")
    parser.add_argument("--density", required=True)
    parser.add_argument("--styles", required=True, help="comma-separated style names of the split")
    parser.add_argument("--methods", default="default,solid_texture,tuned_noise")
    parser.add_argument("--arms", default="", help="a study in experiments/ whose register_arms() adds methods")
    args = parser.parse_args(argv)
    if args.arms:
        import importlib

        sys.path.insert(0, str(ROOT / "experiments"))
        importlib.import_module(args.arms).register_arms()
    from study import score_as_users_see

    from mistyle.benchmark.methods import METHODS, Context, timed
    from mistyle.benchmark.runner import metric_views
    from mistyle.benchmark.splits import split_density, split_pairs, split_styles
    from mistyle.files import load_style
    from mistyle.stylizer import Stylizer

    stylizer = Stylizer(None)
    context = Context(stylizer, metric_views(stylizer.config.render.camera_distance))
    styles = split_styles(args.split)
    for spec, name in split_pairs(args.split, [args.density], args.styles.split(",")):
        density, style = split_density(spec), load_style(styles[name]["path"])
        print(f"== {spec.name} x {name}")
        for method in args.methods.split(","):
            albedo, _ = timed(METHODS[method], context, density, style)
            metrics, images = score_as_users_see(context, density, albedo, style)
            levels = " ".join(
                f"L{i} -" if t is None else f"L{i} mag {t[0]:.2f} ori {t[1]:.2f} lum {t[2]:.2f}"
                for i, t in enumerate(level_terms(images, style))
            )
            print(f"{method:14s} structure {metrics['structure']:.3f}  {levels}", flush=True)


if __name__ == "__main__":
    main()
