"""The validation learning curve: the fidelity benchmark's metrics, path traced, for a run's checkpoints.

Training logs fast-layer metrics on its validation split (``val_rgb_swd`` ...). The benchmark scores
path-traced renders of 64^3 densities, which the layer's single scattering at 32^3 does not predict
well, so checkpoints are chosen here instead: every checkpoint in ``CHECKPOINTS`` (files or folders
of ``*.pt``, e.g. a run's ``steps/``, written with ``run.keep_checkpoints``) stylizes the validation
pairs -- the offline set's held-out paintings (``train.dataset.validation_paintings``) on
``data.heldout.VALIDATION_DENSITIES`` (other seeds than the benchmark's) -- and each albedo is path
traced and scored exactly as ``mistyle-bench`` scores the benchmark, with the ratios
to the uniform baseline (computed once per pair). The benchmark's held-out split is never used.

    python experiments/validation_curve.py runs/cpu_sliced/steps --out results/validation_curve/validation_curve
    python experiments/validation_curve.py a.pt b.pt --res 64 --styles 4        # quicker

Writes ``<out>.jsonl`` (a line per checkpoint and pair, with the albedo's density-weighted level and
spread: ``albedo_statistics``), prints a summary line per checkpoint (medians over pairs) and draws
``<out>.png`` (median RGB / patch SWD ratios and hue coverage against the training step; ``--offset``
adds the steps of the run an ``--init`` started from).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from study import add_metric_arguments

from mistyle.pages import EXPERIMENTS_TITLE, write_index


def checkpoint_files(items: list[str]) -> list[Path]:
    files = []
    for item in map(Path, items):
        files += sorted(item.glob("*.pt")) if item.is_dir() else [item]
    return files


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("checkpoints", nargs="+")
    parser.add_argument("--out", default="results/validation_curve/validation_curve")
    parser.add_argument("--styles", type=int, default=0, help="use only this many paintings (0: all of the split)")
    parser.add_argument(
        "--paintings",
        choices=("validation", "training"),
        default="validation",
        help="score on the held-out validation paintings (choosing checkpoints), or on as many "
        "training paintings, evenly spaced (how much of the network's skill carries to unseen styles)",
    )
    parser.add_argument("--offset", type=int, default=0, help="steps trained before the run's --init")
    add_metric_arguments(parser)
    args = parser.parse_args()

    import torch
    from study import metric_views, score, uniform_baseline

    from mistyle.api import Stylizer
    from mistyle.data.heldout import VALIDATION_DENSITIES, held_out_density
    from mistyle.files import load_style
    from mistyle.model.checkpoint import load_checkpoint
    from mistyle.train.dataset import training_paintings, validation_paintings

    torch.manual_seed(0)
    paintings = validation_paintings()
    if args.paintings == "training":  # the same number, spread over the (sorted) training paintings
        seen = training_paintings()
        paintings = [seen[i] for i in np.linspace(0, len(seen) - 1, len(paintings)).round().astype(int)]
    paintings = paintings[: args.styles or None]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    rows, baselines = [], {}
    for path in checkpoint_files(args.checkpoints):
        stylizer = Stylizer(path)
        config = stylizer.config
        scale, radiance = stylizer.density_scale, config.render.radiance
        views = metric_views(config.render.camera_distance)
        step = int(load_checkpoint(path)["step"]) + args.offset
        mine = []
        for spec in VALIDATION_DENSITIES:
            density = held_out_density(spec, args.cache)
            for painting in paintings:
                style = load_style(painting)
                key = (spec.name, painting.stem)
                if key not in baselines:
                    albedo = uniform_baseline(density, style, views, density_scale=scale, radiance=radiance)
                    baselines[key] = score(
                        density,
                        albedo,
                        style,
                        views,
                        res=args.res,
                        spp=args.spp,
                        density_scale=scale,
                        radiance=radiance,
                    )[0]
                albedo = stylizer(density, style)
                metrics, _ = score(
                    density, albedo, style, views, res=args.res, spp=args.spp, density_scale=scale, radiance=radiance
                )
                metrics.update(albedo_statistics(albedo, density))
                base = baselines[key]
                row = {
                    "checkpoint": str(path),
                    "step": step,
                    "density": spec.name,
                    "style": painting.stem,
                    **metrics,
                    "rgb_swd_ratio": metrics["rgb_swd"] / base["rgb_swd"],
                    "patch_swd_ratio": metrics["patch_swd"] / base["patch_swd"],
                    "uniform_hue_coverage": base["hue_coverage"],
                }
                mine.append(row)
        rows += mine
        summary = {
            "checkpoint": str(path),
            "step": step,
            "pairs": len(mine),
            **{
                key: float(np.median([r[key] for r in mine]))
                for key in (
                    "rgb_swd_ratio",
                    "patch_swd_ratio",
                    "hue_coverage",
                    "rgb_swd",
                    "patch_swd",
                    "albedo_level",
                    "albedo_spread",
                )
            },
        }
        print(json.dumps(summary), flush=True)
    out.with_suffix(".jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    chart(out.with_suffix(".png"), rows)
    write_index(out.parent, EXPERIMENTS_TITLE)


def albedo_statistics(albedo: np.ndarray, density: np.ndarray) -> dict:
    """The albedo ``(Z, Y, X, 3)`` seen as the medium shows it, each voxel weighted by its density (thin fringes
    count little): ``albedo_level``, the weighted mean, and ``albedo_spread``, the weighted standard deviation
    (0 for a uniform albedo), each averaged over R, G and B."""
    weight = (density / density.sum()).reshape(-1, 1)
    colours = albedo.reshape(-1, 3)
    mean = (weight * colours).sum(axis=0)
    spread = np.sqrt((weight * (colours - mean) ** 2).sum(axis=0))
    return {"albedo_level": float(mean.mean()), "albedo_spread": float(spread.mean())}


def chart(path: Path, rows: list[dict], size=(640, 300)) -> None:
    """Median RGB SWD ratio (red), patch SWD ratio (blue) and hue coverage (green) against the step."""
    from PIL import Image, ImageDraw

    steps = sorted({r["step"] for r in rows})
    series = {
        key: [float(np.median([r[key] for r in rows if r["step"] == s])) for s in steps]
        for key in ("rgb_swd_ratio", "patch_swd_ratio", "hue_coverage")
    }
    width, height, margin = size[0], size[1], 40
    image = Image.new("RGB", size, "white")
    draw = ImageDraw.Draw(image)
    low, high = 0.0, max(1.2, max(max(v) for v in series.values()))
    x_of = lambda s: margin + (width - 2 * margin) * (s - steps[0]) / max(steps[-1] - steps[0], 1)  # noqa: E731
    y_of = lambda v: height - margin - (height - 2 * margin) * (v - low) / (high - low)  # noqa: E731
    draw.line([(margin, y_of(1.0)), (width - margin, y_of(1.0))], fill="gray")  # the uniform baseline's ratio
    for values, colour in zip(series.values(), ("red", "blue", "green")):
        xy = [(x_of(s), y_of(v)) for s, v in zip(steps, values)]
        if len(xy) > 1:
            draw.line(xy, fill=colour, width=2)
        for x, y in xy:
            draw.ellipse([x - 3, y - 3, x + 3, y + 3], fill=colour)
    draw.rectangle([margin, margin, width - margin, height - margin], outline="gray")
    draw.text(
        (margin, 8),
        "validation medians: RGB SWD x uniform (red), patch SWD x uniform (blue), hue coverage (green)",
        fill="black",
    )
    draw.text((margin, 22), f"grey line: the uniform baseline (1.0); y 0-{high:.2f}", fill="black")
    draw.text((margin, height - margin + 8), f"training step {steps[0]} - {steps[-1]}", fill="black")
    image.save(path)


if __name__ == "__main__":
    main()
