"""A look over a held-out sequence: flicker, and frames away from the key frames (issue: looks).

The held-out smoke64 simulation (``mistyle.data.heldout.held_out_sequence``; its frame 69 is the
benchmark's smoke64) is stylized over ``--count`` frames from ``--first`` with each style in two ways:

* ``network``: ``mistyle-render --refine 0``'s feed-forward sequence (the network, the colour match
  fitted on the first frame and shared);
* ``look``: a look fitted on the first, middle and last frame, applied to every frame without
  refinement: ``mistyle-render``'s default for a sequence (``Pipeline.fits_look``) and
  ``--save-look``'s.

Per arm and style it records the albedo flicker (``objective.metrics.temporal_flicker``, warped by
the velocities), and for the look the benchmark's metrics of every frame (``study.score``,
its metric views), split into key frames and the others, with the fit's and the application's
seconds. The contact sheet shows per style: the style, the look's frames over time, ``mistyle-render``'s
default output of the middle frame (since #32 a look fitted on that frame alone,
``Pipeline.fits_look``), smooth noise with the colour match, and the uniform baseline (the benchmark's
``smooth_noise`` and ``uniform``); the table also scores the middle frame by the network with the
colour match and the density ramp with it (``density_ramp``).

    python experiments/look_sequence.py                      # 19 frames, 3 styles
    python experiments/look_sequence.py --quick              # 4 frames, 1 style, 3 fit steps
Writes ``results/look_sequence/`` (rows.jsonl, table.md, sheet.jpg).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

STYLES = "hokusai_great_wave,texture_rusty_metal,van_gogh_starry_night"


def main() -> None:
    from study import add_metric_arguments

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--first", type=int, default=60)
    parser.add_argument("--count", type=int, default=19)
    parser.add_argument("--styles", default=STYLES)
    parser.add_argument("--sheet-frames", type=int, default=5, help="look frames shown over time on the sheet")
    parser.add_argument("--out", type=Path, default=Path("results/look_sequence"))
    parser.add_argument("--quick", action="store_true")
    add_metric_arguments(parser)
    args = parser.parse_args()
    if args.quick:
        args.first, args.count, args.styles, args.res, args.spp = 69, 4, "hokusai_great_wave", 32, 4
        args.out = Path("runs/look_sequence_quick")
    run(args)


def run(args) -> None:
    from study import metric_views, score

    from mistyle.benchmark.methods import Context, colour_matched, density_ramp, smooth_noise, uniform_albedo
    from mistyle.data.heldout import held_out_sequence, held_out_styles
    from mistyle.files import load_style
    from mistyle.look import LookSettings
    from mistyle.objective.metrics import temporal_flicker
    from mistyle.pipeline import Pipeline, PipelineSettings
    from mistyle.tone import display

    densities, velocities = held_out_sequence(args.first, args.count, Path(args.cache))
    pipeline = Pipeline(PipelineSettings(refine_steps=0, refine_path_steps=0))
    stylizer = pipeline.stylizer
    views = metric_views(pipeline.camera_distance)
    options = dict(res=args.res, spp=args.spp, density_scale=pipeline.density_scale, radiance=pipeline.radiance)
    context = Context(stylizer, views, quick=args.quick)
    middle = len(densities) // 2
    shown = np.linspace(0, len(densities) - 1, args.sheet_frames).round().astype(int)
    styles = held_out_styles()
    args.out.mkdir(parents=True, exist_ok=True)
    rows, sheet = [], []
    for name in args.styles.split(","):
        style = load_style(styles[name]["path"])
        started = time.perf_counter()
        network = stylizer(densities, style)
        network_seconds = (time.perf_counter() - started) / len(densities)
        settings = LookSettings(steps=3) if args.quick else None
        look = pipeline.fit_look(list(densities), style, look_settings=settings)
        applied, look_albedos = [], []
        for density in densities:
            started = time.perf_counter()
            look_albedos.append(look.stylize(density))
            applied.append(time.perf_counter() - started)
        keys = set(look.meta["key_frames"])
        frames, tiles = [], {}
        for index, (density, albedo) in enumerate(zip(densities, look_albedos)):
            metrics, images = score(density, albedo, style, views, **options)
            frames.append({"frame": args.first + index, "key": index in keys, **metrics})
            if index in shown:
                tiles[f"look t={args.first + index}"] = display(images[0])
        density = densities[middle]
        default = Pipeline(PipelineSettings(), stylizer=stylizer).stylize(density, style).albedos[0]
        uniform = uniform_albedo(context, density, style)
        noise = colour_matched(context, smooth_noise(density.shape, context.seed), density, style)
        ramp = colour_matched(context, density_ramp(density), density, style)
        references = {}
        compared = (
            ("default (middle frame)", default),
            ("network", network[middle]),
            ("noise + match", noise),
            ("ramp + match", ramp),
            ("uniform", uniform),
        )
        for label, albedo in compared:
            metrics, images = score(density, albedo, style, views, **options)
            references[label] = metrics
            tiles[label] = display(images[0])
        row = {
            "style": name,
            "frames": [args.first, args.first + len(densities) - 1],
            "key_frames": [args.first + k for k in sorted(keys)],
            "flicker_network": temporal_flicker(np.stack(network), velocities),
            "flicker_look": temporal_flicker(np.stack(look_albedos), velocities),
            "fit_seconds": look.meta["fit_seconds"],
            "apply_seconds_per_frame": float(np.mean(applied)),
            "network_seconds_per_frame": network_seconds,
            "per_frame": frames,
            "look_middle_frame": frames[middle],
            "references_middle_frame": references,
        }
        for part, chosen in (("key", True), ("other", False)):
            for metric in ("rgb_swd", "patch_swd", "hue_coverage"):
                values = [f[metric] for f in frames if f["key"] == chosen and f[metric] is not None]
                row[f"{part}_{metric}"] = float(np.mean(values)) if values else None
        rows.append(row)
        sheet.append((name, style, tiles))
        print(json.dumps({k: v for k, v in row.items() if k not in ("per_frame", "references_middle_frame")}))
    (args.out / "rows.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    (args.out / "table.md").write_text(table(rows))
    write_sheet(sheet, args.out / "sheet.jpg")
    print((args.out / "table.md").read_text())


def table(rows: list[dict]) -> str:
    lines = [
        "| style | flicker look / network | key frames RGB / patch SWD | other frames RGB / patch SWD | "
        "other / key (RGB, patch) | fit s | apply s/frame |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        lines.append(
            f"| {row['style']} | {row['flicker_look'] / row['flicker_network']:.2f} "
            f"({row['flicker_look']:.4f} / {row['flicker_network']:.4f}) | "
            f"{row['key_rgb_swd']:.4f} / {row['key_patch_swd']:.4f} | "
            f"{row['other_rgb_swd']:.4f} / {row['other_patch_swd']:.4f} | "
            f"{row['other_rgb_swd'] / row['key_rgb_swd']:.2f}, {row['other_patch_swd'] / row['key_patch_swd']:.2f} | "
            f"{row['fit_seconds']:.0f} | {row['apply_seconds_per_frame']:.2f} |"
        )
    labels = list(rows[0]["references_middle_frame"]) if rows else []
    lines += [
        "",
        "The middle frame, RGB / patch SWD (lower is closer to the style): the sequence's look beside "
        "`mistyle-render`'s default for that frame alone (a look fitted on it), the network with the colour match "
        "(`--refine 0`) and the benchmark's baselines with the same colour match (smooth noise, the density "
        "ramp) and the uniform fill.",
        "",
        "| style | look (sequence) | " + " | ".join(labels) + " |",
        "|---|---|" + "---|" * len(labels),
    ]
    for row in rows:
        look = row["look_middle_frame"]
        cells = [f"{look['rgb_swd']:.4f} / {look['patch_swd']:.4f}"] + [
            f"{row['references_middle_frame'][label]['rgb_swd']:.4f} / "
            f"{row['references_middle_frame'][label]['patch_swd']:.4f}"
            for label in labels
        ]
        lines.append(f"| {row['style']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def write_sheet(sheet: list, path: Path, tile: int = 128) -> None:
    """Per style a row: the style, the look's frames over time, the default output, noise + match, uniform."""
    from PIL import Image, ImageDraw

    from mistyle.model.features import square_style

    columns = 1 + max(len(tiles) for _, _, tiles in sheet)
    canvas = np.ones((len(sheet) * (tile + 14), columns * tile, 3), np.float32)
    labels = []
    for row, (name, style, tiles) in enumerate(sheet):
        top = row * (tile + 14) + 14
        cells = [square_style(style, tile).permute(1, 2, 0).numpy()]
        for image in tiles.values():
            cells.append(np.asarray(Image.fromarray((image * 255 + 0.5).astype(np.uint8)).resize((tile, tile))) / 255)
        canvas[top : top + tile, : len(cells) * tile] = np.concatenate(cells, axis=1)
        labels.append((top - 13, [name] + list(tiles)))
    image = Image.fromarray((np.clip(canvas, 0, 1) * 255 + 0.5).astype(np.uint8))
    draw = ImageDraw.Draw(image)
    for top, names in labels:
        for column, label in enumerate(names):
            draw.text((column * tile + 3, top), label[:22], fill="black")
    image.save(path, quality=90)


if __name__ == "__main__":
    main()
