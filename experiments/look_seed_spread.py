"""Which seed moves a look's score: its fit's or its colour match's (issue #35's step-count study).

For each named held-out pair, fits a look (the default settings, no colour match) with each of
``--fit-seeds``, then fits the colour match on that look's albedo with each of ``--match-seeds`` and
scores the matched albedo as the benchmark does (``study.score``). The table gives, per pair
and fit seed, the spread (max/min) of RGB and patch SWD over the match seeds, and per pair the spread
over the fit seeds with the match seed held at 0.

    python experiments/look_seed_spread.py --pairs smoke64:signac_la_calanque,smoke64:munch_the_scream

``--split-fit`` splits the fit's seed further: two more fits per pair, one drawing its views with seed 1
and its sliced objective (projections, the style's subsample) with seed 0, one the other way round
(the objective's seed is set by wrapping ``SlicedObjective``; the colour match takes the views' seed). Rows:
``<out>/seed_split.jsonl``, table ``<out>/seed_split.md``.

Rows: ``<out>/seed_spread.jsonl``; table: ``<out>/seed_spread.md``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

FROZEN_AT = "a2cd51f"
"""The last commit whose ``LookSettings`` has this study's arms (removed from the product on 2026-12-05): a
frozen study, run from a checkout of that commit."""


def main() -> None:
    from study import add_metric_arguments

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--pairs", required=True, help="comma-separated density:style held-out pairs")
    parser.add_argument("--fit-seeds", default="0,1")
    parser.add_argument("--match-seeds", default="0,1,2")
    parser.add_argument("--out", type=Path, default=Path("results/look_speed"))
    parser.add_argument("--split-fit", action="store_true", help="views' seed against the objective's")
    add_metric_arguments(parser)
    args = parser.parse_args()
    from study import require_frozen_commit

    require_frozen_commit(__file__, FROZEN_AT)

    if args.split_fit:
        split_fit(args)
        return

    from mistyle.colour_match import fit_colour_match
    from mistyle.look import LookSettings, fit_look
    from mistyle.style import style_target

    stylizer, pairs, score = setting(args)
    radiance = stylizer.config.render.radiance
    rows = []
    for name, density, style in pairs:
        target = style_target([style], [1.0])
        for fit_seed in map(int, args.fit_seeds.split(",")):
            settings = LookSettings(seed=fit_seed, colour_match="none")
            look = fit_look(stylizer, [density], style, settings=settings)
            albedo = look.network_albedo(density)
            for match_seed in map(int, args.match_seeds.split(",")):
                match = fit_colour_match(
                    albedo,
                    density,
                    target,
                    density_scale=stylizer.density_scale,
                    radiance=radiance,
                    camera_distance=look.camera_distance,
                    seed=match_seed,
                )
                metrics = score(density, match.apply(albedo, density), style)
                record(rows, metrics, pair=name, fit_seed=fit_seed, match_seed=match_seed)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "seed_spread.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    lines = [
        "Spread (max / min) of a look's scores over one seed with the other held: over the colour match's "
        "seeds for each fit seed, and over the fit's seeds with the match seed 0.",
        "",
        "| pair | varied | held | RGB SWD spread | patch SWD spread |",
        "|---|---|---|---|---|",
    ]

    def spread(subset, key):
        values = [row[key] for row in subset]
        return f"{max(values) / min(values):.3f}"

    for pair in dict.fromkeys(row["pair"] for row in rows):
        mine = [row for row in rows if row["pair"] == pair]
        for fit_seed in dict.fromkeys(row["fit_seed"] for row in mine):
            subset = [row for row in mine if row["fit_seed"] == fit_seed]
            lines.append(
                f"| {pair} | match seed | fit seed {fit_seed} | {spread(subset, 'rgb_swd')} | "
                f"{spread(subset, 'patch_swd')} |"
            )
        subset = [row for row in mine if row["match_seed"] == 0]
        lines.append(
            f"| {pair} | fit seed | match seed 0 | {spread(subset, 'rgb_swd')} | {spread(subset, 'patch_swd')} |"
        )
    lines += ["", f"`python experiments/look_seed_spread.py --pairs {args.pairs}`", ""]
    (args.out / "seed_spread.md").write_text("\n".join(lines))


def record(rows: list[dict], metrics: dict, **keys) -> None:
    """Append (and print) the row of one fit: ``keys`` and its two SWDs."""
    row = {**keys, "rgb_swd": metrics["rgb_swd"], "patch_swd": metrics["patch_swd"]}
    print(json.dumps(row), flush=True)
    rows.append(row)


def setting(args):
    """The bundled network, the named held-out pairs ``[(name, density, style)]`` and
    ``score(density, albedo, style) -> metrics`` as the benchmark scores."""
    from study import metric_views, score

    from mistyle.benchmark.splits import split_pairs
    from mistyle.data.heldout import held_out_density, held_out_styles
    from mistyle.files import load_style
    from mistyle.stylizer import Stylizer

    wanted = args.pairs.split(",")
    chosen = [(spec, name) for spec, name in split_pairs("heldout") if f"{spec.name}:{name}" in wanted]
    if len(chosen) != len(wanted):
        raise SystemExit(f"Not all of {wanted} are held-out pairs (density:style).")
    stylizer = Stylizer()
    views = metric_views(stylizer.config.render.camera_distance)
    options = dict(
        res=args.res, spp=args.spp, density_scale=stylizer.density_scale, radiance=stylizer.config.render.radiance
    )
    styles = held_out_styles()
    pairs = [
        (f"{spec.name}:{name}", held_out_density(spec, args.cache), load_style(styles[name]["path"]))
        for spec, name in chosen
    ]
    return stylizer, pairs, lambda density, albedo, style: score(density, albedo, style, views, **options)[0]


def split_fit(args) -> None:
    from mistyle.look import LookSettings, fit_look
    from mistyle.objective import style as objectives

    original = objectives.SlicedObjective
    stylizer, pairs, score = setting(args)
    rows = []
    for name, density, style in pairs:
        for view_seed, objective_seed in ((0, 0), (1, 1), (1, 0), (0, 1)):

            def seeded(*positional, objective_seed=objective_seed, **named):
                return original(*positional, **{**named, "seed": objective_seed})

            objectives.SlicedObjective = seeded
            try:
                # fit_look imports SlicedObjective from its module when it runs, so the wrapper is seen.
                look = fit_look(stylizer, [density], style, settings=LookSettings(seed=view_seed))
            finally:
                objectives.SlicedObjective = original
            metrics = score(density, look.stylize(density), style)
            record(rows, metrics, pair=name, view_seed=view_seed, objective_seed=objective_seed)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "seed_split.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    lines = [
        "A look's scores with its views drawn by one seed and its sliced objective by another (the colour "
        "match's seed is the views' seed; it moves the scores by a few percent, seed_spread.md).",
        "",
        "| pair | views' seed | objective's seed | RGB SWD | patch SWD |",
        "|---|---|---|---|---|",
    ]
    lines += [
        f"| {row['pair']} | {row['view_seed']} | {row['objective_seed']} | {row['rgb_swd']:.5f} | "
        f"{row['patch_swd']:.5f} |"
        for row in rows
    ]
    lines += ["", f"`python experiments/look_seed_spread.py --split-fit --pairs {args.pairs}`", ""]
    (args.out / "seed_split.md").write_text("\n".join(lines))


if __name__ == "__main__":
    main()
