"""Where does direct optimisation's lead over the network sit: in its colours, or in where it puts them? (#13)

On each validation pair (``train.dataset.validation_paintings`` x ``val_smoke64``, never the
benchmark's held-out pairs) the bundled network's albedo and direct optimisation's (the benchmark's
``optimised`` method: ``render_final``'s refinement at twice its steps, from the uniform baseline) are
taken apart and put together again, each arm scored like the benchmark (``study.score``):

* ``network``, ``optimised``, ``uniform``: as in the benchmark.
* ``net place, opt colours``: the network's albedo carried by an iterated sliced optimal transport
  (density-weighted, in log albedo) onto the distribution of optimisation's albedo values: the
  network's arrangement with optimisation's colours.
* ``opt place, net colours``: the reverse: optimisation's arrangement with the network's colours.
* ``opt low-pass s``: optimisation's albedo low-passed (density-weighted Gaussian, ``s`` voxels):
  how much of its lead is in detail finer than ``s``?
* ``net + opt detail``: the network's albedo plus optimisation's detail finer than one voxel (its albedo
  less its ``low-pass 1``): is the detail all the network lacks?
* ``opt coarse + net detail``: optimisation's ``low-pass 2`` plus the network's detail finer than two
  voxels.
* ``colour match``: the network's arrangement with the style's colours, in closed form
  (``mistyle.colour_match``, what ``mistyle.stylize`` does by default); ``colour match, density
  weights``: the same with every voxel counted by its density rather than by how much of it the
  cameras see (``output_corrections.py``'s ``transport s=0`` arm).
  The committed ``results/gap_decomposition/gap_decomposition.md`` predates the colour match's feedback step, which this
  arm now includes; ``colour_match_feedback.py`` compares the two on the same pairs.


Each row also records ``detail_rms``: the density-weighted RMS of each albedo's detail finer than one
voxel, for the network and for optimisation. Every pair's network and optimised albedos are stored
in ``<out>_albedos/`` (``.npz``, float16; not meant for the repository).

Every arm is also scored view by view (``rgb_swd_per_view``: the mean over the metric views of each
view's own RGB SWD), since the benchmark's RGB SWD pools the views' pixels, and an albedo whose views
each show part of the style's colours scores better pooled than any one view looks.

Writes ``<out>.jsonl`` (a line per pair), ``<out>.md`` (medians over pairs of each arm's RGB SWD as a
multiple of optimisation's, pooled and per view, and of the uniform baseline's, patch SWD x uniform,
hue coverage; and how
much the arrangement depends on the style: the density-weighted correlation of two styles' albedos,
each less its mean colour, median over pairs of styles, for the network and for optimisation) and
``<out>.jpg`` (style | network, path traced and its albedo's middle slice | colour match, the same |
optimisation, the same; first
``SHEET_PAIRS`` pairs, held-out view). ``--report-only`` rewrites the ``.md`` and ``.jpg`` from the
``.jsonl`` and the stored albedos, and a rerun reuses the stored optimised albedos (the slow part).

    python experiments/gap_decomposition.py            # 13 pairs: about 30 min on 2 cores
    python experiments/gap_decomposition.py --quick    # 1 pair, small renders and a short optimisation
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
from output_corrections import transported, uniform_response, weighted_lowpass
from study import add_metric_arguments

from mistyle.colour_match import TRANSPORT_SAMPLES, apply_sliced_transport, fit_sliced_transport

ARMS = (
    "network",
    "optimised",
    "net place, opt colours",
    "opt place, net colours",
    "opt low-pass 1",
    "opt low-pass 2",
    "net + opt detail",
    "opt coarse + net detail",
    "colour match, density weights",
    "colour match",
    "uniform",
)
SHEET_PAIRS = 4
ALBEDO_FLOOR = 1e-3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="results/gap_decomposition/gap_decomposition")
    parser.add_argument("--checkpoint", default=None, help="default: the bundled network")
    parser.add_argument("--optimise-factor", type=float, default=2, help="as mistyle-bench's")
    add_metric_arguments(parser)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument(
        "--report-only", action="store_true", help="rewrite the .md and .jpg from the .jsonl and the albedos"
    )
    args = parser.parse_args()
    if args.quick:
        args.res, args.spp, args.out = 32, 4, str(Path(tempfile.mkdtemp()) / "gap_decomposition")
        args.optimise_factor = 0.05

    from study import metric_views, score, uniform_baseline

    from mistyle.api import Stylizer
    from mistyle.data.heldout import VALIDATION_DENSITIES, held_out_density
    from mistyle.files import load_style
    from mistyle.fit import refine_albedo
    from mistyle.integrators import prepare_density
    from mistyle.objective.metrics import style_fidelity
    from mistyle.pipeline import default_refinement
    from mistyle.train.dataset import validation_paintings

    stylizer = Stylizer(args.checkpoint)
    scale, radiance = stylizer.density_scale, stylizer.config.render.radiance
    views = metric_views(stylizer.config.render.camera_distance)
    settings = default_refinement(stylizer.config).scaled(args.optimise_factor)
    paintings = validation_paintings()[: 1 if args.quick else None]
    out = Path(args.out)
    kept = out.parent / f"{out.name}_albedos"
    kept.mkdir(parents=True, exist_ok=True)
    if args.report_only:
        report([json.loads(line) for line in out.with_suffix(".jsonl").read_text().splitlines()], out, args)
        return
    rows = []
    for spec in VALIDATION_DENSITIES:
        density = held_out_density(spec, args.cache)
        prepared = prepare_density(density, scale)
        response = uniform_response(density, scale, radiance, views[0])
        weight = density.astype(np.float64)
        for painting in paintings:
            style = load_style(painting)
            network = stylizer(density, style, match_colours=False)
            uniform = uniform_baseline(density, style, views, density_scale=scale, radiance=radiance)
            stored = kept / f"{spec.name}__{painting.stem}.npz"
            if stored.exists():
                optimised = np.load(stored)["optimised"].astype(np.float32)
            else:
                optimised, _ = refine_albedo(
                    density, scale, uniform, style, settings, radiance=radiance, prepared=prepared
                )
            np.savez_compressed(stored, network=network.astype(np.float16), optimised=optimised.astype(np.float16))
            low = {
                (name, sigma): weighted_lowpass(albedo.astype(np.float64), weight, sigma)
                for name, albedo in (("network", network), ("optimised", optimised))
                for sigma in (1.0, 2.0)
            }
            albedos = {
                "network": network,
                "optimised": optimised,
                "uniform": uniform,
                "net place, opt colours": recoloured(network, optimised, weight),
                "opt place, net colours": recoloured(optimised, network, weight),
                "opt low-pass 1": low["optimised", 1.0],
                "opt low-pass 2": low["optimised", 2.0],
                "net + opt detail": network + (optimised - low["optimised", 1.0]),
                "opt coarse + net detail": low["optimised", 2.0] + (network - low["network", 2.0]),
                "colour match, density weights": transported(network, density, style, response, sigma=0.0),
                "colour match": stylizer.match_colours([network], [density], style)[0],
            }
            albedos = {arm: np.clip(albedo, 0.0, 1.0).astype(np.float32) for arm, albedo in albedos.items()}
            row = {
                "density": spec.name,
                "style": painting.stem,
                "detail_rms": {
                    name: detail_rms(albedo, low[name, 1.0], weight)
                    for name, albedo in (("network", network), ("optimised", optimised))
                },
            }
            for arm in ARMS:
                row[arm], images = score(
                    density,
                    albedos[arm],
                    style,
                    views,
                    res=args.res,
                    spp=args.spp,
                    density_scale=scale,
                    radiance=radiance,
                )
                row[arm]["rgb_swd_per_view"] = float(
                    np.mean([style_fidelity(image[None], style)["rgb_swd"] for image in images])
                )
            rows.append(row)
            print(json.dumps(row), flush=True)
    out.with_suffix(".jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    report(rows, out, args)


def report(rows: list[dict], out: Path, args) -> None:
    """``<out>.md`` and ``<out>.jpg`` from the rows and the albedos kept in ``<out>_albedos/``."""
    from study import metric_views, score

    from mistyle.api import Stylizer
    from mistyle.data.heldout import VALIDATION_DENSITIES, held_out_density
    from mistyle.files import load_style
    from mistyle.pages import EXPERIMENTS_TITLE, write_grid, write_index
    from mistyle.tone import display
    from mistyle.train.dataset import validation_paintings

    stylizer = Stylizer(args.checkpoint)
    scale, radiance = stylizer.density_scale, stylizer.config.render.radiance
    views = metric_views(stylizer.config.render.camera_distance)
    specs = {spec.name: spec for spec in VALIDATION_DENSITIES}
    paintings = {painting.stem: painting for painting in validation_paintings()}
    kept = out.parent / f"{out.name}_albedos"
    albedos = {(r["density"], r["style"]): np.load(kept / f"{r['density']}__{r['style']}.npz") for r in rows}
    dependence = {}
    for name in ("network", "optimised"):
        correlations = []
        for density_name in {r["density"] for r in rows}:
            weight = held_out_density(specs[density_name], args.cache).astype(np.float64)
            fields = [albedos[key][name].astype(np.float64) for key in albedos if key[0] == density_name]
            correlations += [pattern_correlation(a, b, weight) for i, a in enumerate(fields) for b in fields[i + 1 :]]
        dependence[name] = float(np.median(correlations))
    text = table(rows) + (
        f"\nThe same arrangement whatever the style? Density-weighted correlation of two styles' albedos on "
        f"the same density, each less its mean colour (median over pairs of styles): network "
        f"{dependence['network']:.2f}, optimisation {dependence['optimised']:.2f}.\n"
    )
    out.with_suffix(".md").write_text(text)
    print(text)
    sheet = []
    for r in rows[:SHEET_PAIRS]:
        density = held_out_density(specs[r["density"]], args.cache)
        style = load_style(paintings[r["style"]])
        tiles = [(style, r["style"][:18])]
        for name in ("network", "colour match", "optimised"):
            stored = albedos[r["density"], r["style"]]
            albedo = (
                stylizer.match_colours([stored["network"].astype(np.float32)], [density], style)[0]
                if name == "colour match"
                else stored[name].astype(np.float32)
            )
            _, images = score(
                density, albedo, style, views[:1], res=args.res, spp=args.spp, density_scale=scale, radiance=radiance
            )
            middle = albedo.shape[0] // 2  # the slice through the volume's centre, black where there is no medium
            tiles += [
                (display(images[0]), name),
                (display(albedo[middle] * (density[middle, ..., None] > 0)), f"{name[:12]}: slice"),
            ]
        sheet.append(tiles)
    write_grid(out.with_suffix(".jpg"), sheet)
    write_index(out.parent, EXPERIMENTS_TITLE)


def recoloured(arrangement: np.ndarray, colours: np.ndarray, weight: np.ndarray, seed: int = 0) -> np.ndarray:
    """``arrangement (Z, Y, X, 3)`` moved by sliced optimal transport (in log albedo, voxels counted by
    ``weight``) onto the distribution of ``colours (Z, Y, X, 3)``'s values."""
    rng = np.random.default_rng(seed)
    p = weight.ravel() / weight.sum()
    source = np.log(np.clip(arrangement, ALBEDO_FLOOR, 1.0)).reshape(-1, 3).astype(np.float64)
    target = np.log(np.clip(colours, ALBEDO_FLOOR, 1.0)).reshape(-1, 3).astype(np.float64)
    stages = fit_sliced_transport(
        source[rng.choice(len(p), TRANSPORT_SAMPLES, p=p)], target[rng.choice(len(p), TRANSPORT_SAMPLES, p=p)], rng
    )
    inside = weight.ravel() > 0
    result = source.copy()
    result[inside] = apply_sliced_transport(stages, source[inside])
    return np.clip(np.exp(result), 0.0, 1.0).reshape(arrangement.shape).astype(np.float32)


def pattern_correlation(first: np.ndarray, second: np.ndarray, weight: np.ndarray) -> float:
    """Density-weighted correlation over voxels and channels of two albedos ``(Z, Y, X, 3)``, each less its
    density-weighted mean colour."""
    w = weight[..., None] / weight.sum()
    a, b = first - np.sum(w * first, axis=(0, 1, 2)), second - np.sum(w * second, axis=(0, 1, 2))
    return float(np.sum(w * a * b) / np.sqrt(np.sum(w * a * a) * np.sum(w * b * b)))


def detail_rms(albedo: np.ndarray, low: np.ndarray, weight: np.ndarray) -> float:
    """Density-weighted RMS over voxels and channels of ``albedo - low``."""
    return float(np.sqrt(np.sum(weight[..., None] * (albedo - low) ** 2) / (3 * np.sum(weight))))


def table(rows: list[dict]) -> str:
    """Medians over pairs: RGB SWD as multiples of optimisation's and of the uniform baseline's, patch SWD x
    uniform, hue coverage."""
    lines = [
        f"Medians over {len(rows)} validation pairs (lower is better, hue coverage higher is better).",
        "",
        "| arm | RGB SWD x optimised | per view | RGB SWD x uniform | patch SWD x uniform | hue coverage |",
        "|---|---|---|---|---|---|",
    ]
    for arm in ARMS:

        def median_ratio(key, reference):
            return float(np.median([r[arm][key] / r[reference][key] for r in rows]))

        coverage = float(np.median([r[arm]["hue_coverage"] for r in rows]))
        lines.append(
            f"| {arm} | {median_ratio('rgb_swd', 'optimised'):.2f} | "
            f"{median_ratio('rgb_swd_per_view', 'optimised'):.2f} | "
            f"{median_ratio('rgb_swd', 'uniform'):.3f} | "
            f"{median_ratio('patch_swd', 'uniform'):.3f} | {coverage:.3f} |"
        )
    lines.append("")
    for name in ("network", "optimised"):
        lines.append(
            f"Detail finer than one voxel (density-weighted RMS, median over pairs), {name}: "
            f"{np.median([r['detail_rms'][name] for r in rows]):.4f}  "
        )
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
