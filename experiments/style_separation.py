"""Does each style get its own look? How far apart the renders of different styles are, next to the styles.

The fidelity benchmark scores each (density, style) pair on its own, so a network that gives every
style one shared, middling palette can still beat the uniform baseline pair by pair. This asks the
question across styles: the validation paintings (``train.dataset.validation_paintings``) stylize
``val_smoke64`` one by one with each method, every albedo is path traced from the benchmark's metric
views (``experiments/study.py``), and for every pair of paintings (A, B):

* **separation** = ``SWD(render_A, render_B) / SWD(style_A, style_B)``: the sliced W1 distance between
  the two renders' foreground colours over the one between the two paintings' colours. 0: the renders
  look alike whatever the style; 1: they are as far apart as the paintings.
* **own-style preference**: the fraction of ordered pairs where render A is closer to style A than to
  style B (``SWD(render_A, style_A) < SWD(render_A, style_B)``). 0.5 is chance.

Methods: each checkpoint given (default: the bundled network), the uniform baseline (the style's mean
colour, matched through the renderer) and direct optimisation from it (the benchmark's ``optimised``,
about a minute per painting; ``--no-optimised`` leaves it out).

    python experiments/style_separation.py --styles 8 --out results/style_separation/style_separation
    python experiments/style_separation.py runs/a.pt --styles 4 --res 64 --no-optimised     # quicker

Writes ``<out>.json`` (per method: medians and every pair) and prints a table.
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path

import numpy as np
from study import add_metric_arguments


def paintings_apart(styles: dict) -> dict:
    """``{(a, b): SWD(style_a, style_b)}`` for every unordered pair of names (sorted) of ``styles``: name ->
    ``(M, 3)`` painting colours. The denominators of the separation, the same for every method."""
    from mistyle.objective.metrics import sliced_wasserstein

    return {
        (a, b): sliced_wasserstein(styles[a], styles[b], order=1) for a, b in itertools.combinations(sorted(styles), 2)
    }


def separation_summary(renders: dict, styles: dict, apart: dict) -> dict:
    """``renders``: painting name -> ``(N, 3)`` foreground colours of its render; ``styles``: name ->
    ``(M, 3)`` painting colours (the same names); ``apart``: ``paintings_apart(styles)``. Medians of the
    separation and the own-style preference over the pairs, and every pair."""
    from mistyle.objective.metrics import sliced_wasserstein

    names = sorted(renders)
    if len(names) < 2 or set(names) != set(styles):
        raise ValueError(f"need the same two or more paintings in renders and styles, got {names} and {sorted(styles)}")
    to_style = {(a, b): sliced_wasserstein(renders[a], styles[b], order=1) for a in names for b in names}
    pairs = []
    for a, b in itertools.combinations(names, 2):
        renders_apart = sliced_wasserstein(renders[a], renders[b], order=1)
        pairs.append(
            {
                "a": a,
                "b": b,
                "renders_apart": renders_apart,
                "styles_apart": apart[(a, b)],
                "separation": renders_apart / apart[(a, b)],
                "a_prefers_own": to_style[(a, a)] < to_style[(a, b)],
                "b_prefers_own": to_style[(b, b)] < to_style[(b, a)],
            }
        )
    preference = np.mean([p["a_prefers_own"] for p in pairs] + [p["b_prefers_own"] for p in pairs])
    return {
        "paintings": len(names),
        "separation": float(np.median([p["separation"] for p in pairs])),
        "own_style_preference": float(preference),
        "pairs": pairs,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("checkpoints", nargs="*", help="SKPN checkpoints (default: the bundled one)")
    parser.add_argument("--styles", type=int, default=8, help="the first this many validation paintings (0: all 13)")
    parser.add_argument(
        "--no-optimised", action="store_true", help="leave out direct optimisation (a minute per painting)"
    )
    parser.add_argument("--optimise-factor", type=float, default=2, help="as mistyle-bench's")
    parser.add_argument("--out", default="results/style_separation/style_separation")
    add_metric_arguments(parser)
    args = parser.parse_args()

    import torch
    from study import metric_views, score, uniform_baseline

    from mistyle.api import Stylizer
    from mistyle.data.heldout import VALIDATION_DENSITIES, held_out_density
    from mistyle.files import load_style
    from mistyle.fit import refine_albedo
    from mistyle.integrators import prepare_density
    from mistyle.objective.metrics import foreground_pixels
    from mistyle.pipeline import default_refinement
    from mistyle.train.dataset import validation_paintings

    torch.manual_seed(0)
    paintings = validation_paintings()[: args.styles or None]
    stylizers = {Path(c).stem if c else "bundled": Stylizer(c) for c in (args.checkpoints or [None])}
    reference = next(iter(stylizers.values()))  # light, scale and views of the first network
    config = reference.config
    scale, radiance = reference.density_scale, config.render.radiance
    views = metric_views(config.render.camera_distance)
    density = held_out_density(VALIDATION_DENSITIES[0], args.cache)
    prepared = None if args.no_optimised else prepare_density(density, scale)
    settings = default_refinement(config).scaled(args.optimise_factor)

    styles = {p.stem: load_style(p) for p in paintings}
    renders: dict[str, dict] = {}

    def keep(method, name, albedo):
        _, images = score(
            density, albedo, styles[name], views, res=args.res, spp=args.spp, density_scale=scale, radiance=radiance
        )
        renders.setdefault(method, {})[name] = np.concatenate([foreground_pixels(image) for image in images])

    for name, style in styles.items():
        for label, stylizer in stylizers.items():
            keep(f"network:{label}", name, stylizer(density, style))
        uniform = uniform_baseline(density, style, views, density_scale=scale, radiance=radiance)
        keep("uniform", name, uniform)
        if prepared is not None:
            keep(
                "optimised",
                name,
                refine_albedo(density, scale, uniform, style, settings, radiance=radiance, prepared=prepared)[0],
            )
        print(f"{name}: rendered", flush=True)

    colours = {name: style.reshape(-1, 3) for name, style in styles.items()}
    apart = paintings_apart(colours)
    results = {method: separation_summary(found, colours, apart) for method, found in renders.items()}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(
        json.dumps(
            {"density": VALIDATION_DENSITIES[0].name, "res": args.res, "spp": args.spp, "methods": results}, indent=1
        )
    )
    print(
        f"\n{len(paintings)} validation paintings on {VALIDATION_DENSITIES[0].name}, medians over "
        f"{len(paintings) * (len(paintings) - 1) // 2} pairs\n"
    )
    print("| method | separation (renders apart / paintings apart) | own-style preference |")
    print("|---|---|---|")
    for method, summary in results.items():
        print(f"| {method} | {summary['separation']:.2f} | {summary['own_style_preference']:.2f} |")


if __name__ == "__main__":
    main()
