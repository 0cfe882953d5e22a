"""The SKPN paper's design choices, one arm per choice, measured with the fidelity benchmark (#14).

Every arm trains ``configs/ablation.toml`` (the paper's design at a reduced CPU scale) with one
change, for the same step budget, data and seeds, then stylizes held-out (density, style) pairs
that training never saw and scores them as ``mistyle-bench`` does: path traced (volpath,
multiple scattering, the training light) from 3 views around the orbit, RGB SWD, patch SWD and hue
coverage, each also as a ratio to the must-beat uniform baseline of that pair. Claims:

1. DAIN vs plain instance normalisation (also: RGB SWD and hue coverage on the thin and the dense
   parts of each render, split by the opacity of the medium along each pixel's ray)
2. the histogram feature loss vs Gram matrices vs mean/std, and the fidelity study's sliced objective
3. four stylizing kernels vs two and one
4. 1x1x1 predicted kernels vs 3x3x3
5. four views per training step vs one (also: the spread of RGB SWD over 8 views around the orbit,
   and RGB SWD from 2 views above and below the elevations training ever renders from)
6. the temporal loss on vs off (also: flicker, the mean |V_t - W(V_{t-1})| of the albedo over 5 frames
   of the held-out smoke64 plume, with and without the velocity warp)
7. kernel prediction vs AdaIN-style modulation, at its own size and widened to the same parameter count
8. the fast layer vs the path tracer (no training: ``layer_vs_pathtraced.py``'s JSON, ``--layer-json``;
   its contact sheet: the layer beside volpath at 1, 16 and 256 spp on that experiment's scene, timed)

Runs are kept under ``--runs``, one per setting and seed (the paper's arm of every claim is one run
per seed, shared; a finished run is reused),
results are appended to ``results/ablations/ablations.jsonl`` (one line per claim, arm, seed and pair),
``results/ablations/ablations_table.md`` holds the per-arm means and spreads over seeds, and
``results/ablations/ablations_claim<N>.jpg`` is each claim's contact sheet: a row per arm (its first seed's
network), three held-out pairs path traced from the held-out view, under the styles and the uniform
baseline.

    python experiments/ablations.py --claims 4                 # one claim, 3 seeds per arm
    python experiments/ablations.py --claims all               # every claim (hours on 2 cores)
    python experiments/ablations.py --claims 1,3 --base sliced  # the same arms on mistyle's sliced objective
    python experiments/ablations.py --claims 8 --layer-json out.json   # claim 8 from layer_vs_pathtraced.py
    python experiments/ablations.py --report-only              # rewrite the table from the jsonl
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from dataclasses import dataclass
from pathlib import Path

from study import add_metric_arguments

from mistyle.pages import EXPERIMENTS_TITLE, write_index

HERE = Path(__file__).resolve().parent
REPO = HERE.parent

BASE_CONFIG = REPO / "configs" / "ablation.toml"
EVAL_DENSITIES = ("smoke64", "pyroclastic64")
EVAL_STYLES = ("hokusai_great_wave", "munch_the_scream", "photo_nasa_carina_pillar", "texture_rusty_metal")
SPREAD_VIEWS = 8
# Training draws views on CameraPath's orbit, whose elevation stays within 10 +- 20 degrees; these two
# (elevation in degrees, orbit position) lie outside it, seeing the medium from well above and below.
OFF_ORBIT_VIEWS = ((60.0, 0.1), (-45.0, 0.6))
FLICKER_FRAMES = 5  # consecutive frames of the held-out smoke64 plume, from its benchmark frame on
FLICKER_STYLES = ("hokusai_great_wave", "munch_the_scream")
SHEET_PAIRS = (
    ("smoke64", "hokusai_great_wave"),
    ("smoke64", "munch_the_scream"),
    ("pyroclastic64", "photo_nasa_carina_pillar"),
)
SHEET_TILE, SHEET_SPP = 128, 32
THIN_OPACITY = 0.5  # a pixel is thin where less than half the light from behind is absorbed or scattered away
DENSE_OPACITY = 0.9  # and dense where more than 90% is


@dataclass(frozen=True)
class Claim:
    title: str
    arms: dict  # arm name -> config overrides (SECTION.KEY=VALUE); the first arm is the paper's choice
    view_spread: bool = False
    flicker: bool = False
    regions: bool = False
    unit: str = ""  # what a bare-number arm counts, for the contact sheet's labels


CLAIMS = {
    1: Claim("DAIN vs instance normalisation", {"DAIN": [], "instance norm": ['model.norm="in"']}, regions=True),
    2: Claim(
        "style loss",
        {
            "histogram": ['loss.style="histogram"'],
            "Gram": ['loss.style="gram"'],
            "mean/std": ['loss.style="meanstd"'],
            "sliced (fidelity study)": ['loss.objective="sliced"', 'loss.mask="body"'],
        },
    ),
    3: Claim(
        "number of stylizing kernels",
        {"4": ["model.kernels=4"], "2": ["model.kernels=2"], "1": ["model.kernels=1"]},
        unit="kernels",
    ),
    4: Claim("predicted kernel size", {"1x1x1": ["model.kernel_size=1"], "3x3x3": ["model.kernel_size=3"]}),
    5: Claim(
        "views per training step", {"4": ["render.views=4"], "1": ["render.views=1"]}, view_spread=True, unit="views"
    ),
    6: Claim(
        "temporal loss", {"on": ["loss.temporal_weight=300.0"], "off": ["loss.temporal_weight=0.0"]}, flicker=True
    ),
    7: Claim(
        "kernel prediction vs AdaIN",
        {
            "kernels": ['model.stylize="kernel"'],
            "AdaIN": ['model.stylize="adain"'],
            # A wider style predictor brings AdaIN to the kernel arm's parameter count (321,623 vs 321,707).
            "AdaIN, same size": ['model.stylize="adain"', "model.style_hidden=177"],
        },
    ),
}
LAYER_CLAIM = 8
BASES = {
    "paper": [],
    # The paper's design trained with the objective mistyle's fidelity study chose (claim 2's best arm),
    # so each design choice is also measured where the network beats the uniform baseline.
    "sliced": ['loss.objective="sliced"', 'loss.mask="body"'],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--claims", default="all", help="comma-separated claim numbers 1-8, or all")
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument(
        "--base",
        choices=sorted(BASES),
        default="paper",
        help="what every arm starts from: the paper's design, or it with mistyle's sliced objective",
    )
    parser.add_argument("--steps", type=int, default=None, help="training steps per run (default: the config's)")
    parser.add_argument("--runs", type=Path, default=REPO / "runs" / "ablations")
    parser.add_argument("--out", type=Path, default=REPO / "results" / "ablations" / "ablations")
    add_metric_arguments(parser)
    parser.add_argument("--layer-json", type=Path, default=None, help="claim 8: layer_vs_pathtraced.py's output line")
    parser.add_argument(
        "--rescore", action="store_true", help="score finished runs again (new rows replace old ones in the table)"
    )
    parser.add_argument("--report-only", action="store_true")
    args = parser.parse_args()
    claims = sorted(set(CLAIMS) | {LAYER_CLAIM}) if args.claims == "all" else [int(c) for c in args.claims.split(",")]
    unknown = [c for c in claims if c not in CLAIMS and c != LAYER_CLAIM]
    if unknown:
        parser.error(f"no claim {unknown}; the claims are 1-8")
    if args.base != "paper" and 2 in claims:
        parser.error("claim 2 compares objectives, so it runs on the paper's base only")
    jsonl = args.out.with_suffix(".jsonl")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if not args.report_only:
        seeds = [int(s) for s in args.seeds.split(",")]
        for number in claims:
            if number == LAYER_CLAIM:
                if args.layer_json is None:
                    print(
                        "claim 8 needs --layer-json (run experiments/layer_vs_pathtraced.py > out.json)",
                        file=sys.stderr,
                    )
                    continue
                row = layer_row(args.layer_json)
                append(jsonl, row)  # the table keeps the newest layer row (newest_rows)
                layer_sheet(args, row["rel_rmse_single"])
                continue
            for arm, overrides in CLAIMS[number].arms.items():
                for seed in seeds:
                    run_arm(number, arm, BASES[args.base] + overrides, seed, args, jsonl)
            contact_sheet(number, seeds[0], args)
    rows = newest_rows(read_rows(jsonl))
    table = args.out.parent / f"{args.out.name}_table.md"
    table.write_text(report(rows))
    write_index(table.parent, EXPERIMENTS_TITLE)
    print(f"wrote {table}")


def run_folder(overrides: list, seed: int, args):
    """``(config, folder)`` of one arm's run: arms with the same effective settings (the paper's arm of
    every claim) share one run per seed."""
    from mistyle.model.config import load_config

    settings = [*overrides, f"run.seed={seed}"] + ([f"optim.steps={args.steps}"] if args.steps else [])
    config = load_config(BASE_CONFIG, settings)
    return config, args.runs / run_name(overrides) / f"steps{config.optim.steps}_seed{seed}"


def run_arm(number: int, arm: str, overrides: list, seed: int, args, jsonl: Path) -> None:
    """Train one (claim, arm, seed) on ``args.base`` unless its run finished before, then score it unless
    already scored."""
    done = {(r["claim"], r.get("base", "paper"), r["arm"], r["seed"]) for r in read_rows(jsonl)}
    if (number, args.base, arm, seed) in done and not args.rescore:
        return
    import torch

    from mistyle.train.trainer import Trainer

    config, out = run_folder(overrides, seed, args)
    if not (out / "final.pt").exists():
        Trainer(config, out, resume=(out / "last.pt").exists()).run()
    train_seconds = float(torch.load(out / "final.pt", map_location="cpu", weights_only=True)["seconds"])
    rows = score_run(out / "final.pt", CLAIMS[number], args)
    if CLAIMS[number].flicker:
        flicker = sequence_flicker(out / "final.pt", args)
        rows = [{**row, **flicker} for row in rows]
    for row in rows:
        append(
            jsonl,
            {
                "claim": number,
                "base": args.base,
                "arm": arm,
                "seed": seed,
                "overrides": overrides,
                "steps": config.optim.steps,
                "train_seconds": train_seconds,
                **row,
            },
        )


def score_run(checkpoint: Path, claim: Claim, args) -> list[dict]:
    """Fidelity metrics of a checkpoint on the held-out pairs, each with its uniform baseline's ratio,
    and the claim's extra metrics (view spread, thin/dense regions)."""
    from study import metric_views, score

    from mistyle.api import Stylizer
    from mistyle.data.heldout import (
        HELD_OUT_DENSITIES,
        held_out_density,
        held_out_styles,
    )
    from mistyle.files import load_style
    from mistyle.objective.metrics import multiview_spread, style_fidelity

    stylizer = Stylizer(checkpoint)
    scale, radiance = stylizer.density_scale, stylizer.config.render.radiance
    views = metric_views(stylizer.config.render.camera_distance)
    parameters = sum(p.numel() for p in stylizer.trained.model.parameters())
    specs = {spec.name: spec for spec in HELD_OUT_DENSITIES}
    styles = held_out_styles()
    rows = []
    for density_name in EVAL_DENSITIES:
        density = held_out_density(specs[density_name], args.cache)
        opacities = view_opacity(density, views, args.res, scale) if claim.regions else None
        for style_name in EVAL_STYLES:
            style = load_style(styles[style_name]["path"])
            albedo = stylizer(density, style)
            metrics, images = score(
                density, albedo, style, views, res=args.res, spp=args.spp, density_scale=scale, radiance=radiance
            )
            uniform = uniform_metrics(
                f"{density_name}/{style_name}", density, style, views, scale, radiance, args, opacities
            )
            if opacities is not None:
                metrics.update(region_fidelity(images, opacities, style))
            ratios = [key for key in metrics if key in uniform and (key.endswith("rgb_swd") or key == "patch_swd")]
            row = {
                "density": density_name,
                "style": style_name,
                "parameters": parameters,
                **metrics,
                **{f"{key}_x_uniform": metrics[key] / uniform[key] for key in ratios},
            }
            if claim.view_spread:
                around = metric_views(stylizer.config.render.camera_distance, SPREAD_VIEWS)
                _, images = score(
                    density, albedo, style, around, res=args.res, spp=args.spp, density_scale=scale, radiance=radiance
                )
                per_view = [style_fidelity([image], style)["rgb_swd"] for image in images]
                row["rgb_swd_view_spread"] = multiview_spread(per_view)["relative_std"]
                unseen = off_orbit_views(stylizer.config.render.camera_distance)
                off, _ = score(
                    density, albedo, style, unseen, res=args.res, spp=args.spp, density_scale=scale, radiance=radiance
                )
                off_uniform = uniform_metrics(
                    f"{density_name}/{style_name}/off_orbit",
                    density,
                    style,
                    unseen,
                    scale,
                    radiance,
                    args,
                    colour_views=views,
                )
                row["off_orbit_rgb_swd_x_uniform"] = off["rgb_swd"] / off_uniform["rgb_swd"]
            rows.append(row)
            print(json.dumps({key: (round(v, 4) if isinstance(v, float) else v) for key, v in row.items()}), flush=True)
    return rows


def off_orbit_views(camera_distance: float) -> list:
    """``OFF_ORBIT_VIEWS`` as ``View``s at the orbit's distance."""
    from mistyle.scenes import CameraPath

    return [
        CameraPath(distance=camera_distance, elevation_deg=elevation, elevation_wobble_deg=0.0).view(u)
        for elevation, u in OFF_ORBIT_VIEWS
    ]


def contact_sheet(number: int, seed: int, args) -> None:
    """``<out>_claim<N>.jpg``: the styles, the uniform baseline, then a row per arm (its ``seed`` run) on
    ``SHEET_PAIRS``, path traced from the held-out view."""
    from study import metric_views, uniform_baseline

    from mistyle.api import Stylizer, display, path_trace
    from mistyle.data.heldout import (
        HELD_OUT_DENSITIES,
        held_out_density,
        held_out_styles,
    )
    from mistyle.files import load_style
    from mistyle.model.features import square_style
    from mistyle.pages import write_grid

    claim = CLAIMS[number]
    checkpoints = {
        arm: run_folder(BASES[args.base] + overrides, seed, args)[1] / "final.pt"
        for arm, overrides in claim.arms.items()
    }
    missing = [arm for arm, path in checkpoints.items() if not path.exists()]
    if missing:
        print(f"claim {number}: no contact sheet, arms {missing} have no seed-{seed} run", file=sys.stderr)
        return
    specs = {spec.name: spec for spec in HELD_OUT_DENSITIES}
    records = held_out_styles()
    densities = {name: held_out_density(specs[name], args.cache) for name, _ in SHEET_PAIRS}
    styles = {name: load_style(records[name]["path"]) for _, name in SHEET_PAIRS}
    stylizers = {arm: Stylizer(path) for arm, path in checkpoints.items()}
    first = next(iter(stylizers.values()))
    scale, radiance = first.density_scale, first.config.render.radiance
    views = metric_views(first.config.render.camera_distance)

    def tile(density, albedo):
        image = path_trace(
            density, albedo, views[:1], res=SHEET_TILE, spp=SHEET_SPP, density_scale=scale, light=f"constant:{radiance}"
        )[0][0]
        return display(image)

    rows = [
        [(square_style(styles[style], SHEET_TILE).permute(1, 2, 0).numpy(), style[:20]) for _, style in SHEET_PAIRS],
        [
            (
                tile(
                    densities[d],
                    uniform_baseline(densities[d], styles[s], views, density_scale=scale, radiance=radiance),
                ),
                f"uniform, {d}",
            )
            for d, s in SHEET_PAIRS
        ],
    ]
    for arm, stylizer in stylizers.items():
        label = f"{arm} {claim.unit}".strip()[:21]
        rows.append(
            [
                (tile(densities[d], stylizer(densities[d], styles[s])), label if column == 0 else "")
                for column, (d, s) in enumerate(SHEET_PAIRS)
            ]
        )
    suffix = "" if args.base == "paper" else f"_{args.base}"
    path = write_grid(args.out.parent / f"{args.out.name}_claim{number}{suffix}.jpg", rows, SHEET_TILE)
    print(f"wrote {path}")


def layer_sheet(args, layer_error: float) -> None:
    """``<out>_claim8.jpg``: one view of ``layer_vs_pathtraced.py``'s scene (its pyroclastic sphere and
    colour-noise albedo, 64^3) from the fast layer, then volpath (single scattering, pixel centres
    like the layer) at 1, 16 and 256 spp, each with its render time and its relative RMSE to a
    volpath reference (2 x 1024 spp, its own noise taken out: ``pathtrace.net_rel_rmse``). The
    layer's error is below that reference's noise, so its label gives ``layer_error``, which
    ``layer_vs_pathtraced.py`` measured against 2 x 4096 spp."""
    import time

    from layer_vs_pathtraced import scene_inputs

    from mistyle.api import display
    from mistyle.backend import use_variant
    from mistyle.conventions import DEFAULT_DENSITY_SCALE
    from mistyle.integrators import layer_scene, prepare_density
    from mistyle.pages import write_grid
    from mistyle.pathtrace import (
        net_rel_rmse,
        pixel_centre_estimate,
        two_seed_reference,
    )
    from mistyle.scenes import pathtraced_scene, split_views

    mi = use_variant("cpu")
    density, albedo, views = scene_inputs(64, view_count=2)
    views = views[:1]
    layer = mi.load_dict(
        layer_scene(prepare_density(density, DEFAULT_DENSITY_SCALE, 128), albedo, views, res=SHEET_TILE)
    )
    split_views(mi.render(layer), 1)  # compile
    started = time.perf_counter()
    fast = split_views(mi.render(layer), 1)[0]
    tiles = [(fast, f"layer, {time.perf_counter() - started:.3f} s, {100 * layer_error:.2f}%")]
    volpath = mi.load_dict(
        pathtraced_scene(
            density, albedo, views, res=SHEET_TILE, density_scale=DEFAULT_DENSITY_SCALE, max_depth=2, batch=True
        )
    )
    reference, noise_var = two_seed_reference(lambda spp, seed: pixel_centre_estimate(volpath, spp, seed, 1)[0], 1024)

    def error(image):
        return 100 * net_rel_rmse(image, reference, noise_var)

    for spp in (1, 16, 256):
        started = time.perf_counter()
        image = pixel_centre_estimate(volpath, spp, 100 + spp, 1)[0]
        tiles.append((image, f"{spp} spp, {time.perf_counter() - started:.2f} s, {error(image):.0f}%"))
    tiles.append((reference, "volpath, 2 x 1024 spp"))
    path = write_grid(
        args.out.parent / f"{args.out.name}_claim8.jpg",
        [[(display(image), label) for image, label in tiles]],
        SHEET_TILE,
    )
    print(f"wrote {path}")


def view_opacity(density, views, res: int, density_scale: float) -> list:
    """``[(res, res)]`` opacity ``1 - T`` of the medium along each pixel's ray, per view (the torch
    reference march with unit albedo, in-scattering and radiance sums ``T_before - T_after`` to it)."""
    import torch

    from mistyle.reference_torch import render_views_torch

    sigma_t = torch.from_numpy(density).double() * density_scale
    ones = torch.ones((1, 1, *density.shape), dtype=torch.float64)
    opacity = render_views_torch(
        ones, sigma_t, torch.ones_like(sigma_t), views, (res, res), steps=4 * max(density.shape), radiance=1.0
    )
    return list(opacity[0, :, 0].numpy())


def region_fidelity(images: list, opacities: list, style) -> dict:
    """RGB SWD and hue coverage of the foreground pixels that are thin (opacity < ``THIN_OPACITY``) and
    dense (opacity > ``DENSE_OPACITY``), pooled over views: ``thin_rgb_swd``, ``thin_hue_coverage``,
    ``dense_...``, and each region's share of the foreground."""
    import numpy as np

    from mistyle.objective.metrics import (
        foreground_mask,
        hue_coverage,
        sliced_wasserstein,
    )
    from mistyle.tone import display

    style = np.asarray(style, dtype=np.float32)
    masks = [foreground_mask(image) for image in images]
    result = {}
    for region, inside in (("thin", lambda a: a < THIN_OPACITY), ("dense", lambda a: a > DENSE_OPACITY)):
        pixels = np.concatenate(
            [display(image)[mask & inside(alpha)] for image, mask, alpha in zip(images, masks, opacities)]
        )
        result[f"{region}_share"] = len(pixels) / sum(int(mask.sum()) for mask in masks)
        result[f"{region}_rgb_swd"] = (
            sliced_wasserstein(pixels, style.reshape(-1, 3), order=1) if len(pixels) else float("nan")
        )
        result[f"{region}_hue_coverage"] = hue_coverage(pixels, style)
    return result


def sequence_flicker(checkpoint: Path, args) -> dict:
    """Albedo flicker of a checkpoint on the held-out smoke64 plume's frames, mean over ``FLICKER_STYLES``:
    ``flicker`` with the velocity warp (``objective.metrics.temporal_flicker``), ``flicker_unwarped``
    without it."""
    import numpy as np

    from mistyle.api import Stylizer
    from mistyle.data.heldout import held_out_styles
    from mistyle.files import load_style
    from mistyle.objective.metrics import temporal_flicker

    densities, velocities = held_out_sequence(args.cache)
    stylizer = Stylizer(checkpoint)
    styles = held_out_styles()
    warped, unwarped = [], []
    for name in FLICKER_STYLES:
        style = load_style(styles[name]["path"])
        albedos = np.stack([stylizer(density, style) for density in densities])
        warped.append(temporal_flicker(albedos, velocities))
        unwarped.append(float(np.abs(np.diff(albedos, axis=0)).mean()))
    return {"flicker": float(np.mean(warped)), "flicker_unwarped": float(np.mean(unwarped))}


def held_out_sequence(cache: str):
    """``FLICKER_FRAMES`` densities ``(T, Z, Y, X)`` and velocities ``(T, Z, Y, X, 3)`` of the held-out smoke64
    plume from its benchmark frame on (simulated once, cached beside the held-out densities)."""
    from mistyle.data.heldout import HELD_OUT_DENSITIES
    from mistyle.data.heldout import held_out_sequence as frames_of

    spec = next(s for s in HELD_OUT_DENSITIES if s.name == "smoke64")
    return frames_of(spec.frame, FLICKER_FRAMES, Path(cache))


_UNIFORM: dict = {}


def uniform_metrics(name: str, density, style, views, scale, radiance, args, opacities=None, colour_views=None) -> dict:
    """The uniform baseline's metrics for one pair seen from ``views`` (``name``: the pair and, for other
    than the scoring views, which), with ``region_fidelity``'s when given the views' ``opacities``
    (``view_opacity``); computed once per process and cached on disk. The baseline's colour is matched in
    ``colour_views`` (default:
    ``views``), so pass the scoring views to score the same baseline from elsewhere."""
    from study import score, uniform_baseline

    key = f"{name}/{args.res}/{args.spp}"
    cache = args.runs / "uniform.json"
    if not _UNIFORM and cache.exists():
        _UNIFORM.update(json.loads(cache.read_text()))
    if key not in _UNIFORM or (opacities is not None and "thin_rgb_swd" not in _UNIFORM[key]):
        albedo = uniform_baseline(
            density, style, views if colour_views is None else colour_views, density_scale=scale, radiance=radiance
        )
        metrics, images = score(
            density, albedo, style, views, res=args.res, spp=args.spp, density_scale=scale, radiance=radiance
        )
        if opacities is not None:
            metrics.update(region_fidelity(images, opacities, style))
        _UNIFORM[key] = metrics
        cache.parent.mkdir(parents=True, exist_ok=True)
        cache.write_text(json.dumps(_UNIFORM, indent=1))
    return _UNIFORM[key]


def layer_row(path: Path) -> dict:
    """Claim 8 from ``layer_vs_pathtraced.py``'s JSON line: the layer's error and the path tracer's time
    to reach it."""
    result = json.loads(Path(path).read_text().strip().splitlines()[-1])
    return {
        "claim": LAYER_CLAIM,
        "arm": "fast layer",
        "seed": 0,
        "rel_rmse_single": result["rel_rmse_single"],
        "layer_seconds": result["layer_seconds"],
        "pt_spp_equal_error": result["pt_spp_equal_error"],
        "pt_seconds_equal_error": result["pt_seconds_equal_error"],
        "speedup_at_equal_error": result["pt_seconds_equal_error"] / result["layer_seconds"],
        "extrapolated": result["pt_equal_error_extrapolated"],
        "setting": result["setting"],
    }


def report(rows: list[dict]) -> str:
    """Markdown: per claim and arm, the mean over seeds of the per-seed medians over pairs, and the spread."""
    lines = [
        "# Ablations: per-arm results (`experiments/ablations.py`)",
        "",
        "Per arm: the median over held-out pairs of each seed's run, then mean ± spread (max - min) over",
        "seeds. `x uniform`: ratio to the uniform baseline of the same pair (lower is better).",
        "",
    ]
    for number in sorted({r["claim"] for r in rows}):
        claim_rows = [r for r in rows if r["claim"] == number]
        if number == LAYER_CLAIM:
            r = claim_rows[-1]
            lines += [
                "## Claim 8: the fast layer",
                "",
                "| layer rel. RMSE vs volpath | layer s | volpath spp at equal error | volpath s | speed-up |",
                "| --- | --- | --- | --- | --- |",
                f"| {100 * r['rel_rmse_single']:.2f}% | {r['layer_seconds']:.3f} | {r['pt_spp_equal_error']:,.0f}"
                f"{' (extrapolated)' if r['extrapolated'] else ''} | {r['pt_seconds_equal_error']:.0f} | "
                f"{r['speedup_at_equal_error']:,.0f}x |",
                "",
            ]
            continue
        claim = CLAIMS[number]
        extra = (
            (["rgb_swd_view_spread", "off_orbit_rgb_swd_x_uniform"] if claim.view_spread else [])
            + (["flicker", "flicker_unwarped"] if claim.flicker else [])
            + (
                [
                    f"{region}_{metric}"
                    for region in ("thin", "dense")
                    for metric in ("rgb_swd_x_uniform", "hue_coverage")
                ]
                if claim.regions
                else []
            )
        )
        columns = ["rgb_swd_x_uniform", "patch_swd_x_uniform", "hue_coverage", *extra]
        for base in BASES:
            base_rows = [r for r in claim_rows if r.get("base", "paper") == base]
            if not base_rows:
                continue
            on = "" if base == "paper" else f" (on the {base} objective)"
            lines += [
                f"## Claim {number}: {claim.title}{on}",
                "",
                "| arm | seeds | steps | " + " | ".join(columns) + " | rgb_swd_x_uniform per seed | parameters |",
                "| --- | --- | --- | " + " | ".join("---" for _ in columns) + " | --- | --- |",
            ]
            for arm in claim.arms:
                lines.append(arm_line(arm, [r for r in base_rows if r["arm"] == arm], columns))
            lines.append("")
    return "\n".join(lines) + "\n"


def arm_line(arm: str, rows: list[dict], columns: list[str]) -> str:
    """One table row: per column, the mean ± spread over seeds of each seed's median over pairs."""
    seeds = sorted({r["seed"] for r in rows})
    if not seeds:
        return f"| {arm} | not run | | " + " | ".join("" for _ in columns) + " | | |"

    def per_seed(column):
        return [
            statistics.median(values)
            for s in seeds
            if (values := [r[column] for r in rows if r["seed"] == s and column in r])
        ]

    cells = []
    for column in columns:
        values = per_seed(column)
        # Empty: a metric that older runs were not scored with.
        cells.append(f"{statistics.mean(values):.3g} ± {max(values) - min(values):.2g}" if values else "")
    each = ", ".join(f"{v:.2f}" for v in per_seed("rgb_swd_x_uniform"))
    return (
        f"| {arm} | {len(seeds)} | {rows[0]['steps']} | "
        + " | ".join(cells)
        + f" | {each} | {rows[0]['parameters']:,} |"
    )


def newest_rows(rows: list[dict]) -> list[dict]:
    """The last row of each (claim, arm, seed, density, style): a rescore replaces what came before."""
    newest = {
        (r["claim"], r.get("base", "paper"), r["arm"], r["seed"], r.get("density"), r.get("style")): r for r in rows
    }
    return list(newest.values())


def read_rows(jsonl: Path) -> list[dict]:
    return [json.loads(line) for line in jsonl.read_text().splitlines()] if jsonl.exists() else []


def append(jsonl: Path, row: dict) -> None:
    with jsonl.open("a") as handle:
        handle.write(json.dumps(row) + "\n")


def run_name(overrides: list) -> str:
    """A folder name for the settings in ``overrides`` that differ from the base config ("paper": none)."""
    from mistyle.model.config import config_to_dict, load_config

    base = config_to_dict(load_config(BASE_CONFIG))
    changed = [o for o in overrides if config_to_dict(load_config(BASE_CONFIG, [o])) != base]
    return "_".join(slug(o) for o in sorted(changed)) or "paper"


def slug(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name.lower()).strip("_")


if __name__ == "__main__":
    main()
