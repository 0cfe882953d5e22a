"""Cheaper look fits against a reference fit (issue #35, part 2): arms of ``look.LookSettings`` on held-out pairs.

Each arm fits a look on one held-out density with one held-out style (the single-frame default:
the frame is its own key frame), applies it and scores it as the benchmark scores
(``study.score``: 3 metric views, 128^2, 16 spp). Each row keeps its ratios to the
benchmark's ``look`` row of the same pair and metric settings as it was when the row was made
(``--against``; ``x look``) and to its ``smooth_noise`` row; the table gives medians of per-pair
ratios, and the fit's seconds. Arms change ``independent90`` (90 steps, independent views: the default
until 2026-12-03, the fit the benchmark's ``look`` rows came from until then); ``default`` is
``LookSettings()`` as it is now.

    python experiments/look_speed_study.py --arms texture30,head30 --pairs 8     # ARMS below

A look's fit is seeded (its views, the sliced objective's projections, the colour match), and on one
pair two seeds of a fit can differ by more than the arms do. ``--seeds 0,1,2`` fits every arm with
each seed; the table then also compares each arm with ``independent90`` fitted with the same seed on
the same pair (``x reference``), and ``independent90``'s rows at other seeds than 0 give the spread
that the seed alone makes (their ``x look``).

    python experiments/look_speed_study.py --arms independent90,head60 --pairs 8 --seeds 0,1,2

``--versus default`` adds a table of every arm against ``default`` fitted with the same seed on the same
pair, with the structure distance beside the SWDs:

    python experiments/look_speed_study.py --arms default,coarse60_fine30 --pairs 8 --versus default \\
        --out results/look_coarse

Rows: ``<out>/rows.jsonl`` (a row per arm, pair and seed, replaced when rerun); table: ``<out>/table.md``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

FIXED = dict(tune_sites=(), tune_decoder=())
# The reference every arm was measured against until 2026-12-03: 90 steps, independent views (the
# default then). Each arm below changes it; "default" is whatever LookSettings' defaults are now.
REFERENCE = "independent90"
BEFORE = dict(steps=90, view_sampling="independent")
ARMS = {
    REFERENCE: BEFORE,
    "default": dict(),
    **{
        name: {**BEFORE, **change}
        for name, change in {
            "head30": dict(steps=30),
            "head60": dict(steps=60),
            "head45": dict(steps=45),
            "head60_lr1.5x": dict(steps=60, lr=0.03, texture_lr=0.075),
            "head45_lr2x": dict(steps=45, lr=0.04, texture_lr=0.1),
            "conv90": dict(tune_sites=()),
            "conv60_lr1.5x": dict(steps=60, tune_sites=(), lr=0.03, texture_lr=0.075),
            "texture30": dict(steps=30, **FIXED),
            "texture30_lr0.1": dict(steps=30, texture_lr=0.1, **FIXED),
            "texture20_lr0.1": dict(steps=20, texture_lr=0.1, **FIXED),
            "texture60": dict(steps=60, **FIXED),
            "texture90": dict(steps=90, **FIXED),
            "texture60_lr0.1": dict(steps=60, texture_lr=0.1, **FIXED),
            "texture90_lr0.1": dict(steps=90, texture_lr=0.1, **FIXED),
            "texture30_res32": dict(steps=30, layer_res=32, **FIXED),
            "texture30_res32_v1": dict(steps=30, layer_res=32, views_per_step=1, **FIXED),
            "cos90": dict(lr_schedule="cosine"),
            "cos60_lr1.5x": dict(steps=60, lr=0.03, texture_lr=0.075, lr_schedule="cosine"),
            "cos45_lr2x": dict(steps=45, lr=0.04, texture_lr=0.1, lr_schedule="cosine"),
            "cos30_lr2x": dict(steps=30, lr=0.04, texture_lr=0.1, lr_schedule="cosine"),
            "stratified": dict(view_sampling="stratified"),
            "stratified60": dict(steps=60, view_sampling="stratified"),
        }.items()
    },
    # Against "default" (--versus default): a coarse stage first (LookSettings.coarse_steps), then fine steps.
    "coarse60_fine30": dict(coarse_steps=60, steps=30),
    # Against "default": each step's projections drawn from a pool of 1024, the style's sorted once.
    "pool1024": dict(direction_pool=1024),
    # Against "default": fewer or smaller views a step (#35's "fewer or smaller views per step").
    "views2": dict(views_per_step=2),
    "res48": dict(layer_res=48),
}


def read(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()] if path.exists() else []


def seed_of(row: dict) -> int:
    return int(row.get("seed", row["settings"].get("seed", 0)))


def write_table(out: Path, rows: list[dict], versus: str | None = None) -> None:
    lines = [
        "Medians over the pairs (and seeds) each arm ran on of per-pair ratios (lower is better) to the "
        "benchmark's `look` row as it was when the row was made (seed 0) and its `smooth_noise` row; "
        f"`x reference`: geometric means of the ratios to `{REFERENCE}` (90 steps, independent views) fitted "
        "with the same seed on the same pair; fit "
        "seconds on this machine with whatever else ran.",
        "",
        "| arm | seeds | pairs x seeds | RGB x look | patch x look | RGB x noise | patch x noise | "
        "RGB x reference (geo. mean) | patch x reference (geo. mean) | fit s (median) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    references = {(row["density"], row["style"], seed_of(row)): row for row in rows if row["arm"] == REFERENCE}
    for arm, seeds in dict.fromkeys((row["arm"], row["arm"] == REFERENCE and seed_of(row) > 0) for row in rows):
        mine = [row for row in rows if row["arm"] == arm and (arm != REFERENCE or (seed_of(row) > 0) == seeds)]

        def median(key, mine=mine):
            return float(np.median([row[key] for row in mine]))

        def against_reference(metric, mine=mine):
            ratios = [
                row[metric] / references[key][metric]
                for row in mine
                if (key := (row["density"], row["style"], seed_of(row))) in references
            ]
            return f"{float(np.exp(np.mean(np.log(ratios)))):.3f} ({len(ratios)})" if ratios else "-"

        label = f"{REFERENCE} (seeds > 0)" if seeds else arm
        lines.append(
            f"| {label} | {','.join(map(str, sorted({seed_of(row) for row in mine})))} | {len(mine)} | "
            f"{median('rgb_x_look'):.3f} | {median('patch_x_look'):.3f} | {median('rgb_x_noise'):.3f} | "
            f"{median('patch_x_noise'):.3f} | {against_reference('rgb_swd')} | {against_reference('patch_swd')} | "
            f"{median('fit_seconds'):.2f} |"
        )
    per_pair_lines = []
    for arm in dict.fromkeys(row["arm"] for row in rows if row["arm"] != REFERENCE):
        mine = [row for row in rows if row["arm"] == arm]
        if len({seed_of(row) for row in mine}) < 2:
            continue
        per_pair: dict = {}
        for row in mine:
            key = (row["density"], row["style"], seed_of(row))
            if key in references:
                ratio = (row["rgb_swd"] / references[key]["rgb_swd"], row["patch_swd"] / references[key]["patch_swd"])
                per_pair.setdefault(key[:2], []).append(np.log(ratio))
        means = {pair: np.exp(np.mean(logs, axis=0)) for pair, logs in per_pair.items()}
        cells = []
        for column in (0, 1):
            worst = max(means, key=lambda pair, column=column: means[pair][column])
            better = sum(value[column] < 1 for value in means.values())
            cells += [f"{better} of {len(means)}", f"{means[worst][column]:.3f} ({worst[0]} x {worst[1]})"]
        per_pair_lines.append(f"| {arm} | {len(means)} | " + " | ".join(cells) + " |")
    if per_pair_lines:
        lines += [
            "",
            f"Per pair, for the arms fitted with several seeds: the geometric mean over the seeds of the ratios to "
            f"`{REFERENCE}` at the same seed; pairs below 1 (better), and the worst pair.",
            "",
            "| arm | pairs | RGB: pairs better | RGB: worst pair | patch: pairs better | patch: worst pair |",
            "|---|---|---|---|---|---|",
            *per_pair_lines,
        ]
    if versus is not None:
        lines += versus_table(rows, versus)
    (out / "table.md").write_text("\n".join(lines) + "\n")


def versus_table(rows: list[dict], versus: str) -> list[str]:
    """Each other arm against ``versus`` fitted with the same seed on the same pair: geometric means of
    the per-pair ratios of RGB SWD, patch SWD and the structure distance, and the pairs where it is lower."""
    lines = [
        "",
        f"Against `{versus}` fitted with the same seed on the same pair: geometric mean of the ratios (lower is "
        "better) and the pair-seeds where the arm is lower.",
        "",
        "| arm | pair-seeds | RGB SWD | patch SWD | structure | fit s (median) |",
        "|---|---|---|---|---|---|",
    ]
    base = {(row["density"], row["style"], seed_of(row)): row for row in rows if row["arm"] == versus}
    for arm in dict.fromkeys(row["arm"] for row in rows if row["arm"] != versus):
        keyed = [(row, (row["density"], row["style"], seed_of(row))) for row in rows if row["arm"] == arm]
        mine = [
            (row, base[key]) for row, key in keyed if key in base and "structure" in row and "structure" in base[key]
        ]
        if not mine:
            continue
        cells = []
        for metric in ("rgb_swd", "patch_swd", "structure"):
            ratios = np.array([row[metric] / other[metric] for row, other in mine])
            cells.append(f"{float(np.exp(np.mean(np.log(ratios)))):.3f} ({int((ratios < 1).sum())} lower)")
        seconds = float(np.median([row["fit_seconds"] for row, _ in mine]))
        lines.append(f"| {arm} | {len(mine)} | " + " | ".join(cells) + f" | {seconds:.2f} |")
    return lines


FROZEN_AT = "a2cd51f"
"""The last commit whose ``LookSettings`` has this study's arms (removed from the product on 2026-12-05): a
frozen study, run from a checkout of that commit."""


def main() -> None:
    from study import add_metric_arguments

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--arms", default="texture30")
    parser.add_argument("--pairs", type=int, default=0, help="N pairs spread over the held-out split (0: all)")
    parser.add_argument("--seeds", default="0", help="comma-separated seeds each arm is fitted with")
    parser.add_argument("--versus", default=None, help="also compare every arm with this one (same pair and seed)")
    parser.add_argument("--against", type=Path, default=Path("results/benchmark"), help="the benchmark's rows")
    parser.add_argument("--out", type=Path, default=Path("results/look_speed"))
    add_metric_arguments(parser)
    args = parser.parse_args()
    from study import require_frozen_commit

    require_frozen_commit(__file__, FROZEN_AT)

    from study import metric_views, score

    from mistyle.benchmark.runner import ROWS_FILE, code_commit
    from mistyle.benchmark.splits import split_pairs
    from mistyle.data.heldout import held_out_density, held_out_styles
    from mistyle.files import load_style
    from mistyle.look import LookSettings, fit_look
    from mistyle.stylizer import Stylizer

    unknown = [arm for arm in args.arms.split(",") if arm not in ARMS]
    if unknown:
        raise SystemExit(f"Unknown arm(s) {', '.join(unknown)}; choose from {', '.join(ARMS)}.")
    reference = {}
    for row in read(args.against / ROWS_FILE):
        settings = row["settings"]
        if settings["res"] == args.res and settings["spp"] == args.spp and not settings["quick"]:
            reference[(row["method"], row["density"], row["style"])] = row
    seeds = [int(seed) for seed in args.seeds.split(",")]
    stylizer = Stylizer()
    views = metric_views(stylizer.config.render.camera_distance)
    options = dict(
        res=args.res, spp=args.spp, density_scale=stylizer.density_scale, radiance=stylizer.config.render.radiance
    )
    styles = held_out_styles()
    pairs = split_pairs("heldout")
    pairs = pairs[:: max(1, len(pairs) // args.pairs)][: args.pairs] if args.pairs else pairs
    args.out.mkdir(parents=True, exist_ok=True)
    rows_path = args.out / "rows.jsonl"
    for spec, style_name in pairs:
        look_row = reference.get(("look", spec.name, style_name))
        noise_row = reference.get(("smooth_noise", spec.name, style_name))
        if look_row is None or noise_row is None:
            print(f"skipped {spec.name} x {style_name}: no look or smooth_noise row in {args.against}")
            continue
        density = held_out_density(spec, args.cache)
        style = load_style(styles[style_name]["path"])
        for arm, seed in [(arm, seed) for seed in seeds for arm in args.arms.split(",")]:
            started = time.perf_counter()
            look = fit_look(stylizer, [density], style, settings=LookSettings(**{**ARMS[arm], "seed": seed}))
            fitted = time.perf_counter() - started
            metrics = score(density, look.stylize(density), style, views, **options)[0]
            row = {
                "arm": arm,
                "settings": ARMS[arm],
                "seed": seed,
                "density": spec.name,
                "style": style_name,
                "rgb_swd": metrics["rgb_swd"],
                "patch_swd": metrics["patch_swd"],
                "rgb_x_look": metrics["rgb_swd"] / look_row["rgb_swd"],
                "patch_x_look": metrics["patch_swd"] / look_row["patch_swd"],
                "structure": metrics["structure"],
                "rgb_x_noise": metrics["rgb_swd"] / noise_row["rgb_swd"],
                "patch_x_noise": metrics["patch_swd"] / noise_row["patch_swd"],
                "fit_seconds": fitted,
                "commit": code_commit(),
            }
            print(json.dumps(row), flush=True)
            rows = [
                old
                for old in read(rows_path)
                if (old["arm"], old["density"], old["style"], seed_of(old)) != (arm, spec.name, style_name, seed)
            ]
            rows_path.write_text("".join(json.dumps(r) + "\n" for r in rows + [row]))
    write_table(args.out, read(rows_path), args.versus)


if __name__ == "__main__":
    main()
