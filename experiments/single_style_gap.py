"""Where the network's gap to direct optimisation lies: one network per style (#13, a diagnostic).

The bundled network is 2x direct optimisation's RGB SWD on the benchmark. This splits that gap in two:
a copy of the bundled network is trained on for ``--steps`` steps on *one* validation painting (the
run's config, ``configs/cpu_sliced_finetune.toml``, with that painting as the whole style set, no hue
rotation and a constant learning rate), and then scored beside the bundled network, the uniform
baseline and direct optimisation (``render_final``'s refinement at twice its steps, from the
baseline) on held-out densities, path traced as the benchmark scores (``study.score``).

* What the one-style network closes is the part of the gap that comes from carrying *many* styles:
  predicting the right kernels for a style the network never saw.
* What it leaves is the part that one style's kernels and this architecture, trained through the
  fast layer on 32^3 plumes, cannot reach on a 64^3 path-traced plume.

The styles are validation paintings (``train.dataset.validation_paintings``), never the benchmark's
held-out ones (the style folder refuses those), and nothing trained here is shipped. The training
folder holds 20 copies of the painting, so that the folder's hash split keeps some for validation.

Writes ``<out>.jsonl`` (a line per density and style) and ``<out>.md``.

    python experiments/single_style_gap.py            # 2 styles x 400 steps (15 min each) + scoring: about 45 min
    python experiments/single_style_gap.py --quick    # 1 style, 4 steps, small renders
    python experiments/single_style_gap.py --styles seurat_circus_sideshow --steps 1200 \
        --checkpoint seurat_circus_sideshow=runs/single_seurat_long/steps/step_000800.pt \
        --out results/single_style_gap/single_style_gap_1200
        # score a one-style network trained elsewhere (here: 800 more steps, learning rate decayed)
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from study import add_metric_arguments

from mistyle.pages import EXPERIMENTS_TITLE, write_index

CONFIG = "configs/cpu_sliced_finetune.toml"
COPIES = 20


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--styles",
        default="congo_raffia_textiles,seurat_circus_sideshow",
        help="validation paintings (stems of train.dataset.validation_paintings)",
    )
    parser.add_argument("--densities", default="val_smoke64,smoke64", help="names in mistyle.data.heldout")
    parser.add_argument(
        "--steps", type=int, default=400, help="one-style training steps (of --checkpoint: as labelled)"
    )
    parser.add_argument(
        "--checkpoint",
        action="append",
        default=[],
        metavar="STYLE=PATH",
        help="score this one-style network for STYLE instead of training one (repeatable)",
    )
    parser.add_argument("--runs", default="runs", help="where the one-style runs go (kept: a rerun scores them again)")
    parser.add_argument("--out", default="results/single_style_gap/single_style_gap")
    add_metric_arguments(parser)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    if args.quick:
        temporary = Path(tempfile.mkdtemp())
        args.styles, args.densities, args.steps = args.styles.split(",")[0], "val_smoke64", 4
        args.res, args.spp, args.runs, args.out = 32, 4, str(temporary / "runs"), str(temporary / "single_style_gap")

    from study import metric_views, score, uniform_baseline

    from mistyle.api import Stylizer
    from mistyle.data.heldout import (
        HELD_OUT_DENSITIES,
        VALIDATION_DENSITIES,
        held_out_density,
    )
    from mistyle.files import load_style
    from mistyle.fit import refine_albedo
    from mistyle.integrators import prepare_density
    from mistyle.pipeline import default_refinement
    from mistyle.train.dataset import validation_paintings

    paintings = {path.stem: path for path in validation_paintings()}
    unknown = [name for name in args.styles.split(",") if name not in paintings]
    if unknown:
        raise SystemExit(f"Not validation paintings: {', '.join(unknown)}; choose from {', '.join(sorted(paintings))}.")
    given = dict(item.split("=", 1) for item in args.checkpoint)
    networks = {
        name: Path(given[name]) if name in given else one_style_network(paintings[name], Path(args.runs), args.steps)
        for name in args.styles.split(",")
    }
    bundled = Stylizer(None)
    scale, radiance = bundled.density_scale, bundled.config.render.radiance
    views = metric_views(bundled.config.render.camera_distance)
    specs = {spec.name: spec for spec in VALIDATION_DENSITIES + HELD_OUT_DENSITIES}
    rows = []
    for density_name in args.densities.split(","):
        density = held_out_density(specs[density_name], args.cache)
        prepared = prepare_density(density, scale)
        for name, checkpoint in networks.items():
            style = load_style(paintings[name])
            albedos = {
                "network": bundled(density, style),
                "one-style network": Stylizer(checkpoint)(density, style),
                "uniform": uniform_baseline(density, style, views, density_scale=scale, radiance=radiance),
            }
            settings = default_refinement(bundled.config).scaled(2 if not args.quick else 0.05)
            albedos["optimised"], _ = refine_albedo(
                density, scale, albedos["uniform"], style, settings, radiance=radiance, prepared=prepared
            )
            row = {"density": density_name, "style": name, "steps": args.steps}
            for method, albedo in albedos.items():
                row[method] = score(
                    density, albedo, style, views, res=args.res, spp=args.spp, density_scale=scale, radiance=radiance
                )[0]
            rows.append(row)
            print(json.dumps(row), flush=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    out.with_suffix(".md").write_text(table(rows))
    write_index(out.parent, EXPERIMENTS_TITLE)
    print(table(rows))


def one_style_network(painting: Path, runs: Path, steps: int) -> Path:
    """The weights after ``steps`` steps of the bundled network on ``painting`` alone (trained unless kept)."""
    run = runs / f"single_{painting.stem}"
    checkpoint = run / "steps" / f"step_{steps:06d}.pt"
    if checkpoint.exists():
        return checkpoint
    folder = runs / "single_styles" / painting.stem
    folder.mkdir(parents=True, exist_ok=True)
    for index in range(COPIES):
        shutil.copy(painting, folder / f"copy{index:02d}{painting.suffix}")
    overrides = {
        "data.styles": folder,
        "data.hue_augment": 0,
        "optim.steps": steps,
        "optim.lr_decay": 1.0,
        "run.eval_every": 10**6,
        "run.checkpoint_every": min(100, steps),
        "run.keep_checkpoints": "true",
    }
    command = [
        sys.executable,
        "-m",
        "mistyle.train",
        "--config",
        CONFIG,
        "--init",
        "mistyle/checkpoints/skpn_cpu.pt",
        "--out",
        str(run),
        "--quiet",
    ] + [item for key, value in overrides.items() for item in ("--set", f"{key}={value}")]
    subprocess.run(command, check=True)
    if not checkpoint.exists():
        raise SystemExit(f"Training {painting.stem} left no {checkpoint}.")
    return checkpoint


def table(rows: list[dict]) -> str:
    """Per pair: RGB SWD / patch SWD / hue coverage of each method, and each network's RGB SWD over optimisation's."""
    methods = ("network", "one-style network", "uniform", "optimised")
    lines = [
        "RGB SWD / patch SWD / hue coverage (lower, lower, higher is better); the last two columns: each network's "
        "RGB SWD as a multiple of direct optimisation's.",
        "",
        "| density | style | " + " | ".join(methods) + " | network / optimised | one-style / optimised |",
        "|---|---|" + "---|" * (len(methods) + 2),
    ]
    for r in rows:
        cells = [f"{r[m]['rgb_swd']:.4f} / {r[m]['patch_swd']:.4f} / {r[m]['hue_coverage']:.2f}" for m in methods]
        ratios = [r[m]["rgb_swd"] / r["optimised"]["rgb_swd"] for m in ("network", "one-style network")]
        lines.append(
            f"| {r['density']} | {r['style']} | " + " | ".join(cells) + f" | {ratios[0]:.2f} | {ratios[1]:.2f} |"
        )
    medians = [
        float(np.median([r[m]["rgb_swd"] / r["optimised"]["rgb_swd"] for r in rows]))
        for m in ("network", "one-style network")
    ]
    lines += [
        "",
        f"Median RGB SWD over optimisation's: network {medians[0]:.2f}x, one-style network {medians[1]:.2f}x "
        f"({rows[0]['steps']} steps on the one style).",
    ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
