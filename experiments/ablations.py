"""The SKPN paper's design choices, one arm per choice, measured with the fidelity benchmark (#14).

Every arm trains ``configs/ablation.toml`` (the paper's design at a reduced CPU scale) with one
change, for the same step budget, data and seeds, then stylizes held-out (density, style) pairs
that training never saw and scores them as ``style_fidelity.py`` does: path traced (volpath,
multiple scattering, the training light) from 3 views around the orbit, RGB SWD, patch SWD and hue
coverage, each also as a ratio to the must-beat uniform baseline of that pair. Claims:

1. DAIN vs plain instance normalisation
2. the histogram feature loss vs Gram matrices vs mean/std, and the fidelity study's sliced objective
3. four stylizing kernels vs two and one
4. 1x1x1 predicted kernels vs 3x3x3
5. four views per training step vs one (also: the spread of RGB SWD over 8 views around the orbit)
6. the temporal loss on vs off (also: flicker, the mean |V_t - W(V_{t-1})| of the albedo over 5 frames
   of the held-out smoke64 plume, with and without the velocity warp)
7. kernel prediction vs AdaIN-style modulation (parameter counts reported beside)
8. the fast layer vs the path tracer (no training: ``layer_vs_pathtraced.py``'s JSON, ``--layer-json``)

Runs are kept under ``--runs``, one per setting and seed (the paper's arm of every claim is one run
per seed, shared; a finished run is reused),
results are appended to ``docs/ablations.jsonl`` (one line per claim, arm, seed and pair), and
``docs/ablations_table.md`` holds the per-arm means and spreads over seeds.

    python experiments/ablations.py --claims 4                 # one claim, 2 seeds per arm
    python experiments/ablations.py --claims all               # every claim (hours on 2 cores)
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

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))

BASE_CONFIG = REPO / "configs" / "ablation.toml"
EVAL_DENSITIES = ("smoke64", "pyroclastic64")
EVAL_STYLES = ("hokusai_great_wave", "munch_the_scream", "photo_nasa_carina_pillar", "texture_rusty_metal")
SPREAD_VIEWS = 8
FLICKER_FRAMES = 5  # consecutive frames of the held-out smoke64 plume, from its benchmark frame on
FLICKER_STYLES = ("hokusai_great_wave", "munch_the_scream")


@dataclass(frozen=True)
class Claim:
    title: str
    arms: dict  # arm name -> config overrides (SECTION.KEY=VALUE); the first arm is the paper's choice
    view_spread: bool = False
    flicker: bool = False


CLAIMS = {
    1: Claim("DAIN vs instance normalisation", {"DAIN": [], "instance norm": ['model.norm="in"']}),
    2: Claim("style loss", {
        "histogram": ['loss.style="histogram"'],
        "Gram": ['loss.style="gram"'],
        "mean/std": ['loss.style="meanstd"'],
        "sliced (fidelity study)": ['loss.objective="sliced"', 'loss.mask="body"'],
    }),
    3: Claim("number of stylizing kernels", {"4": ["model.kernels=4"], "2": ["model.kernels=2"], "1": ["model.kernels=1"]}),
    4: Claim("predicted kernel size", {"1x1x1": ["model.kernel_size=1"], "3x3x3": ["model.kernel_size=3"]}),
    5: Claim("views per training step", {"4": ["render.views=4"], "1": ["render.views=1"]}, view_spread=True),
    6: Claim("temporal loss", {"on": ["loss.temporal_weight=300.0"], "off": ["loss.temporal_weight=0.0"]}, flicker=True),
    7: Claim("kernel prediction vs AdaIN", {"kernels": ['model.stylize="kernel"'], "AdaIN": ['model.stylize="adain"']}),
}
LAYER_CLAIM = 8


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--claims", default="all", help="comma-separated claim numbers 1-8, or all")
    parser.add_argument("--seeds", default="0,1")
    parser.add_argument("--steps", type=int, default=None, help="training steps per run (default: the config's)")
    parser.add_argument("--runs", type=Path, default=REPO / "runs" / "ablations")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "ablations")
    parser.add_argument("--res", type=int, default=128, help="metric renders' side")
    parser.add_argument("--spp", type=int, default=16, help="metric renders' paths per pixel")
    parser.add_argument("--cache", default="data/heldout", help="where held-out densities are cached")
    parser.add_argument("--layer-json", type=Path, default=None, help="claim 8: layer_vs_pathtraced.py's output line")
    parser.add_argument("--report-only", action="store_true")
    args = parser.parse_args()
    claims = sorted(set(CLAIMS) | {LAYER_CLAIM}) if args.claims == "all" else [int(c) for c in args.claims.split(",")]
    unknown = [c for c in claims if c not in CLAIMS and c != LAYER_CLAIM]
    if unknown:
        parser.error(f"no claim {unknown}; the claims are 1-8")
    jsonl = args.out.with_suffix(".jsonl")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if not args.report_only:
        seeds = [int(s) for s in args.seeds.split(",")]
        for number in claims:
            if number == LAYER_CLAIM:
                if args.layer_json is None:
                    print("claim 8 needs --layer-json (run experiments/layer_vs_pathtraced.py > out.json)", file=sys.stderr)
                    continue
                kept = [r for r in read_rows(jsonl) if r["claim"] != LAYER_CLAIM]  # one layer row, the newest
                jsonl.write_text("".join(json.dumps(r) + "\n" for r in kept))
                append(jsonl, layer_row(args.layer_json))
                continue
            for arm, overrides in CLAIMS[number].arms.items():
                for seed in seeds:
                    run_arm(number, arm, overrides, seed, args, jsonl)
    rows = [json.loads(line) for line in jsonl.read_text().splitlines()] if jsonl.exists() else []
    table = args.out.parent / f"{args.out.name}_table.md"
    table.write_text(report(rows))
    print(f"wrote {table}")


def run_arm(number: int, arm: str, overrides: list, seed: int, args, jsonl: Path) -> None:
    """Train one (claim, arm, seed) unless its run finished before, then score it unless already scored."""
    done = {(r["claim"], r["arm"], r["seed"]) for r in read_rows(jsonl)}
    if (number, arm, seed) in done:
        return
    import torch

    from mistyle.model.config import load_config
    from mistyle.train.trainer import Trainer

    settings = [*overrides, f"run.seed={seed}"] + ([f"optim.steps={args.steps}"] if args.steps else [])
    config = load_config(BASE_CONFIG, settings)
    # Arms with the same effective settings (the paper's arm of every claim) share one run per seed.
    out = args.runs / run_name(overrides) / f"steps{config.optim.steps}_seed{seed}"
    if not (out / "final.pt").exists():
        Trainer(config, out, resume=(out / "last.pt").exists()).run()
    train_seconds = float(torch.load(out / "final.pt", map_location="cpu", weights_only=True)["seconds"])
    rows = score_run(out / "final.pt", CLAIMS[number].view_spread, args)
    if CLAIMS[number].flicker:
        flicker = sequence_flicker(out / "final.pt", args)
        rows = [{**row, **flicker} for row in rows]
    for row in rows:
        append(jsonl, {"claim": number, "arm": arm, "seed": seed, "overrides": overrides,
                       "steps": config.optim.steps, "train_seconds": train_seconds, **row})


def score_run(checkpoint: Path, view_spread: bool, args) -> list[dict]:
    """Fidelity metrics of a checkpoint on the held-out pairs, each with its uniform baseline's ratio."""
    from fidelity_core import metric_views, score

    from mistyle.api import Stylizer
    from mistyle.data.heldout import (
        HELD_OUT_DENSITIES,
        held_out_density,
        held_out_styles,
    )
    from mistyle.io import load_style
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
        for style_name in EVAL_STYLES:
            style = load_style(styles[style_name]["path"])
            albedo = stylizer(density, style)
            metrics, _ = score(density, albedo, style, views, res=args.res, spp=args.spp, density_scale=scale,
                               radiance=radiance)
            uniform = uniform_metrics(density_name, style_name, density, style, views, scale, radiance, args)
            row = {"density": density_name, "style": style_name, "parameters": parameters, **metrics,
                   **{f"{key}_x_uniform": metrics[key] / uniform[key] for key in ("rgb_swd", "patch_swd")}}
            if view_spread:
                around = metric_views(stylizer.config.render.camera_distance, SPREAD_VIEWS)
                _, images = score(density, albedo, style, around, res=args.res, spp=args.spp, density_scale=scale,
                                  radiance=radiance)
                per_view = [style_fidelity([image], style)["rgb_swd"] for image in images]
                row["rgb_swd_view_spread"] = multiview_spread(per_view)["relative_std"]
            rows.append(row)
            print(json.dumps({key: (round(v, 4) if isinstance(v, float) else v) for key, v in row.items()}), flush=True)
    return rows


def sequence_flicker(checkpoint: Path, args) -> dict:
    """Albedo flicker of a checkpoint on the held-out smoke64 plume's frames, mean over ``FLICKER_STYLES``:
    ``flicker`` with the velocity warp (``objective.metrics.temporal_flicker``), ``flicker_unwarped``
    without it."""
    import numpy as np

    from mistyle.api import Stylizer
    from mistyle.data.heldout import held_out_styles
    from mistyle.io import load_style
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
    import numpy as np

    from mistyle.data.heldout import HELD_OUT_DENSITIES
    from mistyle.data.smoke import PlumeConfig, simulate

    path = Path(cache) / f"smoke64_sequence{FLICKER_FRAMES}.npz"
    if not path.exists():
        spec = next(s for s in HELD_OUT_DENSITIES if s.name == "smoke64")
        config = PlumeConfig.random((spec.resolution,) * 3, np.random.default_rng([spec.seed, 0]))
        frames = [(d, v) for t, d, v in simulate(config, spec.frame + FLICKER_FRAMES, seed=spec.seed) if t >= spec.frame]
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, densities=np.stack([d for d, _ in frames]), velocities=np.stack([v for _, v in frames]))
    data = np.load(path)
    return data["densities"].astype(np.float32), data["velocities"].astype(np.float32)


_UNIFORM: dict = {}


def uniform_metrics(density_name, style_name, density, style, views, scale, radiance, args) -> dict:
    """The uniform baseline's metrics for one pair (computed once per process and cached on disk)."""
    from fidelity_core import score, uniform_baseline

    key = f"{density_name}/{style_name}/{args.res}/{args.spp}"
    cache = args.runs / "uniform.json"
    if not _UNIFORM and cache.exists():
        _UNIFORM.update(json.loads(cache.read_text()))
    if key not in _UNIFORM:
        albedo = uniform_baseline(density, style, views, density_scale=scale, radiance=radiance)
        metrics, _ = score(density, albedo, style, views, res=args.res, spp=args.spp, density_scale=scale,
                           radiance=radiance)
        _UNIFORM[key] = metrics
        cache.parent.mkdir(parents=True, exist_ok=True)
        cache.write_text(json.dumps(_UNIFORM, indent=1))
    return _UNIFORM[key]


def layer_row(path: Path) -> dict:
    """Claim 8 from ``layer_vs_pathtraced.py``'s JSON line: the layer's error and the path tracer's time
    to reach it."""
    result = json.loads(Path(path).read_text().strip().splitlines()[-1])
    return {"claim": LAYER_CLAIM, "arm": "fast layer", "seed": 0, "rel_rmse_single": result["rel_rmse_single"],
            "layer_seconds": result["layer_seconds"], "pt_spp_equal_error": result["pt_spp_equal_error"],
            "pt_seconds_equal_error": result["pt_seconds_equal_error"],
            "speedup_at_equal_error": result["pt_seconds_equal_error"] / result["layer_seconds"],
            "extrapolated": result["pt_equal_error_extrapolated"], "setting": result["setting"]}


def report(rows: list[dict]) -> str:
    """Markdown: per claim and arm, the mean over seeds of the per-seed medians over pairs, and the spread."""
    lines = ["# Ablations: per-arm results (`experiments/ablations.py`)", "",
             "Per arm: the median over held-out pairs of each seed's run, then mean ± spread (max - min) over",
             "seeds. `x uniform`: ratio to the uniform baseline of the same pair (lower is better).", ""]
    for number in sorted({r["claim"] for r in rows}):
        claim_rows = [r for r in rows if r["claim"] == number]
        if number == LAYER_CLAIM:
            r = claim_rows[-1]
            lines += ["## Claim 8: the fast layer", "",
                      "| layer rel. RMSE vs volpath | layer s | volpath spp at equal error | volpath s | speed-up |",
                      "| --- | --- | --- | --- | --- |",
                      f"| {100 * r['rel_rmse_single']:.2f}% | {r['layer_seconds']:.3f} | {r['pt_spp_equal_error']:,.0f}"
                      f"{' (extrapolated)' if r['extrapolated'] else ''} | {r['pt_seconds_equal_error']:.0f} | "
                      f"{r['speedup_at_equal_error']:,.0f}x |", ""]
            continue
        claim = CLAIMS[number]
        extra = (["rgb_swd_view_spread"] if claim.view_spread else []) + (["flicker", "flicker_unwarped"] if claim.flicker else [])
        columns = ["rgb_swd_x_uniform", "patch_swd_x_uniform", "hue_coverage", *extra]
        lines += [f"## Claim {number}: {claim.title}", "",
                  "| arm | seeds | steps | " + " | ".join(columns) + " | parameters |",
                  "| --- | --- | --- | " + " | ".join("---" for _ in columns) + " | --- |"]
        for arm in claim.arms:
            arm_rows = [r for r in claim_rows if r["arm"] == arm]
            seeds = sorted({r["seed"] for r in arm_rows})
            if not seeds:
                lines.append(f"| {arm} | not run | | " + " | ".join("" for _ in columns) + " | |")
                continue
            cells = []
            for column in columns:
                per_seed = [statistics.median(r[column] for r in arm_rows if r["seed"] == s) for s in seeds]
                cells.append(f"{statistics.mean(per_seed):.3g} ± {max(per_seed) - min(per_seed):.2g}")
            lines.append(f"| {arm} | {len(seeds)} | {arm_rows[0]['steps']} | " + " | ".join(cells)
                         + f" | {arm_rows[0]['parameters']:,} |")
        lines.append("")
    return "\n".join(lines) + "\n"


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
