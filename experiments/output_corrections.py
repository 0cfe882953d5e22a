"""Closed-form stages after the network: can any of them close the gap to direct optimisation? (#13)

The bundled network places a style's structures but mutes its colours next to direct optimisation
(docs/decisions/2026-11-25-training-notebook.md). Each arm below takes the network's albedo, changes
it without a gradient step, and is scored like the benchmark (path traced from the metric views,
``study.score``) on the validation split only
(``train.dataset.validation_paintings`` x ``val_smoke64``), never the benchmark's held-out pairs:

* ``network``: the albedo as the network predicts it (strength 1).
* ``transport s=<sigma>``: colour transport onto the style's pixel colours. Each albedo value is
  mapped to the colour a uniform medium of that albedo shows (``volpath`` at grey levels, one view,
  per density), that colour field is low-passed with a density-weighted Gaussian of ``sigma`` voxels
  (0: none), an iterated sliced optimal transport (Pitie et al. 2007) carries the low-passed colours,
  each voxel counted in proportion to its density, onto the style's pixels, every voxel moves by
  its low-passed colour's displacement, and the result is mapped back to albedo.
* ``defringe``: below 5% of the peak density the albedo is blended (linearly in density) towards the
  density-weighted local mean colour (Gaussian, 3 voxels): are the thin fringes' colours the problem?
* ``strength 1.3``: the stylizing kernels extrapolated past full strength, ``K_neutral + 1.3 (K -
  K_neutral)`` (``SKPN.neutral_kernels``; ``--strength`` stops at 1): is the network's style too weak?

Writes ``<out>.jsonl`` (a line per pair), ``<out>.md`` (medians over pairs of each arm's ratio to the
uniform baseline of the same pair) and ``<out>.jpg`` (style | arms, first four pairs, held-out view).

    python experiments/output_corrections.py                 # 13 pairs: about 8 min on 2 cores
    python experiments/output_corrections.py --quick         # 1 pair, small renders
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
from study import add_metric_arguments

from mistyle.colour_match import RESPONSE_LEVELS, TRANSPORT_SAMPLES
from mistyle.pages import EXPERIMENTS_TITLE, write_grid, write_index

ARMS = ("network", "transport s=0", "transport s=2", "defringe", "strength 1.3")
SHEET_PAIRS = 4


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="results/output_corrections/output_corrections")
    parser.add_argument("--checkpoint", default=None, help="default: the bundled network")
    add_metric_arguments(parser)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    if args.quick:
        args.res, args.spp, args.out = 32, 4, str(Path(tempfile.mkdtemp()) / "output_corrections")

    from study import metric_views, score, uniform_baseline

    from mistyle.api import Stylizer
    from mistyle.data.heldout import VALIDATION_DENSITIES, held_out_density
    from mistyle.files import load_style
    from mistyle.tone import display
    from mistyle.train.dataset import validation_paintings

    stylizer = Stylizer(args.checkpoint)
    scale, radiance = stylizer.density_scale, stylizer.config.render.radiance
    views = metric_views(stylizer.config.render.camera_distance)
    paintings = validation_paintings()[: 1 if args.quick else None]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    rows, sheet = [], []
    for spec in VALIDATION_DENSITIES:
        density = held_out_density(spec, args.cache)
        response = uniform_response(density, scale, radiance, views[0])
        for painting in paintings:
            style = load_style(painting)
            network = stylizer(density, style)
            albedos = {
                "network": network,
                "transport s=0": transported(network, density, style, response, sigma=0.0),
                "transport s=2": transported(network, density, style, response, sigma=2.0),
                "defringe": defringed(network, density),
                "strength 1.3": extrapolated(stylizer, density, style, 1.3),
            }
            albedos["uniform"] = uniform_baseline(density, style, views, density_scale=scale, radiance=radiance)
            row, tiles = {"density": spec.name, "style": painting.stem}, [(style, painting.stem[:18])]
            for arm, albedo in albedos.items():
                metrics, images = score(
                    density, albedo, style, views, res=args.res, spp=args.spp, density_scale=scale, radiance=radiance
                )
                row[arm] = metrics
                tiles.append((display(images[0]), arm))
            rows.append(row)
            print(json.dumps(row), flush=True)
            if len(sheet) < SHEET_PAIRS:
                sheet.append(tiles)
    out.with_suffix(".jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    out.with_suffix(".md").write_text(table(rows))
    write_grid(out.with_suffix(".jpg"), sheet)
    write_index(out.parent, EXPERIMENTS_TITLE)
    print(table(rows))


def table(rows: list[dict]) -> str:
    """Medians over pairs: RGB and patch SWD as ratios to the same pair's uniform baseline, hue coverage."""
    lines = [
        f"Medians over {len(rows)} validation pairs (ratios to the uniform baseline of the same pair; lower "
        "is better, hue coverage higher is better).",
        "",
        "| arm | RGB SWD x uniform | patch SWD x uniform | hue coverage |",
        "|---|---|---|---|",
    ]
    for arm in ARMS + ("uniform",):
        ratio = {
            key: float(np.median([r[arm][key] / r["uniform"][key] for r in rows])) for key in ("rgb_swd", "patch_swd")
        }
        coverage = float(np.median([r[arm]["hue_coverage"] for r in rows]))
        lines.append(f"| {arm} | {ratio['rgb_swd']:.3f} | {ratio['patch_swd']:.3f} | {coverage:.3f} |")
    return "\n".join(lines) + "\n"


def uniform_response(density: np.ndarray, scale: float, radiance: float, view) -> tuple[np.ndarray, np.ndarray]:
    """``(log levels, shown)``: ``response.uniform_display_response`` at ``RESPONSE_LEVELS`` from one view,
    nudged to strictly increasing so that it inverts."""
    from mistyle.response import uniform_display_response

    shown = uniform_display_response(density, scale, radiance, [view], RESPONSE_LEVELS, res=32, spp=4)
    return np.log(RESPONSE_LEVELS), shown + np.arange(len(shown)) * 1e-9


def transported(albedo, density, style, response, sigma: float, seed: int = 0) -> np.ndarray:
    """The ``transport`` arm (module docstring); ``mistyle.colour_match`` is this arm with visibility weights."""
    from mistyle.colour_match import apply_sliced_transport, fit_sliced_transport

    log_levels, shown_levels = response
    shown = np.interp(np.log(np.clip(albedo, RESPONSE_LEVELS[0], 1.0)), log_levels, shown_levels)
    weight = density.astype(np.float64)
    low = weighted_lowpass(shown, weight, sigma)
    rng = np.random.default_rng(seed)
    voxels = rng.choice(weight.size, TRANSPORT_SAMPLES, p=weight.ravel() / weight.sum())
    pixels = np.asarray(style, np.float64).reshape(-1, 3)
    stages = fit_sliced_transport(low.reshape(-1, 3)[voxels], pixels[rng.choice(len(pixels), TRANSPORT_SAMPLES)], rng)
    inside = weight > 0
    moved = shown.copy()
    moved[inside] += apply_sliced_transport(stages, low[inside]) - low[inside]
    result = np.array(albedo, dtype=np.float32)
    result[inside] = np.exp(
        np.interp(np.clip(moved[inside], shown_levels[0], shown_levels[-1]), shown_levels, log_levels)
    )
    return result


def weighted_lowpass(field: np.ndarray, weight: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian low-pass of ``field (Z, Y, X, C)`` weighted by ``weight (Z, Y, X)``, normalised."""
    if sigma == 0:
        return field
    from scipy.ndimage import gaussian_filter

    total = np.maximum(gaussian_filter(weight, sigma), 1e-12)
    return np.stack([gaussian_filter(field[..., c] * weight, sigma) / total for c in range(field.shape[-1])], -1)


def defringed(albedo, density, threshold: float = 0.05, sigma: float = 3.0) -> np.ndarray:
    """The ``defringe`` arm (module docstring)."""
    local = weighted_lowpass(albedo.astype(np.float64), density.astype(np.float64), sigma)
    body = np.clip(density / (threshold * density.max()), 0.0, 1.0)[..., None]
    return (body * albedo + (1.0 - body) * local).astype(np.float32)


def extrapolated(stylizer, density, style, strength: float) -> np.ndarray:
    """The network's albedo with its kernels at ``strength`` > 1 (module docstring)."""
    from mistyle.model.skpn import StylizingKernels

    kernels = stylizer.kernels(style)
    neutral = stylizer.neutral(kernels, density)
    sites = {
        site: {
            key: neutral.sites[site][key] + strength * (kernels.sites[site][key] - neutral.sites[site][key])
            for key in kernels.sites[site]
        }
        for site in kernels.sites
    }
    return stylizer.network_albedo(density, StylizingKernels(sites), 1.0)


if __name__ == "__main__":
    main()
