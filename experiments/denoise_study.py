"""Denoised final frames against more samples: error to a high-sample reference, time, sequence flicker.

For held-out pairs (the benchmark's smoke64 with held-out styles, the default output's albedo), from
the held-out view at the default resolution:

* a reference of ``--reference-spp`` paths (two renders of half as many with other seeds, so that its
  own noise can be taken out of the error: ``pathtrace.net_rel_rmse``'s rule),
* the default samples (``--spp``) undenoised, denoised by OIDN on the colour alone, and denoised with
  the albedo feature (``mistyle.denoise``),
* ``--spp`` times ``--more`` samples undenoised (what the issue compares with),

each scored by its RMSE to the reference in display space over the medium's foreground. Then a
short held-out smoke sequence from one view, the same albedo on every frame: the mean frame-to-frame
change of the display image over the medium, undenoised and denoised as the product denoises (grain
that changes from frame to frame is flicker).

    python experiments/denoise_study.py                       # results/denoise/
    python experiments/denoise_study.py --styles 1 --reference-spp 256 --sequence 3   # a quick look

Writes ``pairs.jsonl`` (a row per pair, kept between runs: a pair already there is not redone),
``flicker.json``, ``table.md`` and ``sheet.jpg`` (the sequence's frames undenoised and denoised) under
``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

STYLES = ("hokusai_great_wave", "signac_la_calanque", "kandinsky_composition_vii", "texture_mossy_rock")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="results/denoise")
    parser.add_argument("--styles", type=int, default=3, help="how many of the held-out styles listed in STYLES")
    parser.add_argument("--res", type=int, default=256)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--more", type=int, default=16, help="the undenoised comparison has this many times --spp")
    parser.add_argument("--reference-spp", type=int, default=2048)
    parser.add_argument("--sequence", type=int, default=6, help="frames of the flicker check (0: none)")
    args = parser.parse_args()

    from mistyle.benchmark.runner import metric_views
    from mistyle.data.heldout import HELD_OUT_DENSITIES, held_out_density, held_out_sequence, held_out_styles
    from mistyle.denoise import denoise
    from mistyle.files import load_style
    from mistyle.objective.metrics import foreground_mask
    from mistyle.pathtrace import path_trace
    from mistyle.pipeline import Pipeline, PipelineSettings
    from mistyle.tone import display

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    pipeline = Pipeline(PipelineSettings())
    view = metric_views(pipeline.camera_distance)[0]
    scale, light = pipeline.density_scale, pipeline.light()
    spec = next(s for s in HELD_OUT_DENSITIES if s.name == "smoke64")
    density = held_out_density(spec, Path("data") / "heldout")
    styles = held_out_styles()

    def trace(grid, albedo, spp, seed):
        started = time.perf_counter()
        (image,), _ = path_trace(
            grid, albedo, [view], res=args.res, spp=spp, density_scale=scale, light=light, seed=seed
        )
        return image, time.perf_counter() - started

    def denoised(grid, albedo, image, feature: bool):
        started = time.perf_counter()
        aux = albedo_feature(grid, albedo, [view], args.res, scale)[0] if feature else None
        return denoise(image, aux), time.perf_counter() - started

    pairs_path = out / "pairs.jsonl"
    rows = [json.loads(line) for line in pairs_path.read_text().splitlines()] if pairs_path.exists() else []
    done = {row["style"] for row in rows}
    for name in STYLES[: args.styles]:
        if name in done:  # pairs are kept between runs: each costs minutes
            continue
        style = load_style(styles[name]["path"])
        albedo = pipeline.stylize(density, style).albedos[0]
        half = args.reference_spp // 2
        first, _ = trace(density, albedo, half, 101)
        second, _ = trace(density, albedo, half, 102)
        reference = 0.5 * (first + second)
        shown_reference = display(reference)
        mask = foreground_mask(reference)
        noise_var = float(np.mean((display(first) - display(second))[mask] ** 2) / 4.0)

        def error(image):
            mse = float(np.mean((display(image) - shown_reference)[mask] ** 2)) - noise_var
            return float(np.sqrt(max(mse, 0.0)))

        noisy, noisy_seconds = trace(density, albedo, args.spp, 1)
        more, more_seconds = trace(density, albedo, args.spp * args.more, 2)
        colour_only, colour_seconds = denoised(density, albedo, noisy, feature=False)
        with_feature, feature_seconds = denoised(density, albedo, noisy, feature=True)
        row = {
            "style": name,
            "res": args.res,
            "reference_spp": args.reference_spp,
            f"rmse_{args.spp}spp": error(noisy),
            f"rmse_{args.spp * args.more}spp": error(more),
            "rmse_denoised_colour": error(colour_only),
            "rmse_denoised_albedo": error(with_feature),
            f"seconds_{args.spp}spp": noisy_seconds,
            f"seconds_{args.spp * args.more}spp": more_seconds,
            "seconds_denoise_colour": colour_seconds,
            "seconds_denoise_albedo": feature_seconds,
        }
        rows.append(row)
        print(json.dumps(row), flush=True)
        with open(pairs_path, "a") as handle:
            handle.write(json.dumps(row) + "\n")

    flicker, tiles = {}, []
    if args.sequence:
        densities, _ = held_out_sequence(69, args.sequence, Path("data") / "heldout")
        style = load_style(styles[STYLES[0]]["path"])
        albedo = pipeline.stylize(densities[0], style).albedos[
            0
        ]  # one albedo: the change is the medium's and the noise's
        shown, masks = {"noisy": [], "denoised": []}, []
        for t, grid in enumerate(densities):
            noisy, _ = trace(grid, albedo, args.spp, 10 + t)
            cleaned, _ = denoised(grid, albedo, noisy, feature=False)  # the product's denoising
            shown["noisy"].append(display(noisy))
            shown["denoised"].append(display(cleaned))
            masks.append(foreground_mask(noisy) | foreground_mask(cleaned))
            tiles.append([shown["noisy"][-1], shown["denoised"][-1]])
        for key, images in shown.items():
            changes = [
                float(np.mean(np.abs(images[t + 1] - images[t])[masks[t] | masks[t + 1]]))
                for t in range(len(images) - 1)
            ]
            flicker[key] = float(np.mean(changes))
        print(json.dumps({"flicker": flicker}), flush=True)
        (out / "flicker.json").write_text(json.dumps({"frames": args.sequence, "spp": args.spp, **flicker}) + "\n")
    elif (out / "flicker.json").exists():
        flicker = json.loads((out / "flicker.json").read_text())

    write_table(out / "table.md", rows, flicker, args)
    if tiles:
        write_sheet(out / "sheet.jpg", tiles, args)


def albedo_feature(
    density: np.ndarray, albedo: np.ndarray, views: list, res: int, density_scale: float, device: str = "cpu"
) -> list[np.ndarray]:
    """``[(res, res, 3)]`` float32 in [0, 1]: what each pixel's ray sees of ``albedo (Z, Y, X, 3)`` on
    ``density (Z, Y, X)``, composited over the white background, ``sum_i w_i alpha_i + (1 - sum_i w_i)``
    with the fast layer's exact segment weights (its render with ``Ls = 1``, ``Le = 1``): a noise-free
    albedo feature for OIDN, measured against filtering the colour alone."""
    import torch

    from mistyle.bridge_torch import render_views
    from mistyle.integrators import prepare_density

    grid = np.asarray(density, dtype=np.float32)
    prepared = prepare_density(grid, density_scale, ls=np.ones_like(grid))
    colours = torch.from_numpy(np.ascontiguousarray(albedo, dtype=np.float32)).permute(3, 0, 1, 2).to(device)
    with torch.no_grad():
        seen = render_views(colours, prepared, views, res, steps=128, radiance=1.0)
        opacity = render_views(
            torch.ones_like(colours[:1]).expand_as(colours), prepared, views, res, steps=128, radiance=1.0
        )
    feature = (seen + (1.0 - opacity)).clamp(0.0, 1.0)
    return [np.ascontiguousarray(image.permute(1, 2, 0).cpu().numpy(), dtype=np.float32) for image in feature]


def write_table(path: Path, rows: list, flicker: dict, args) -> None:
    more = args.spp * args.more
    lines = [
        f"Display-space RMSE over the medium against a {args.reference_spp}-spp reference (its own noise taken out), "
        f"{args.res}^2, the held-out view; seconds on this machine (load average {os.getloadavg()[0]:.1f} at the end).",
        "",
        f"| style | {args.spp} spp | denoised, colour only | denoised, albedo feature | {more} spp | "
        f"time {args.spp} spp + denoise (colour) | time {more} spp | time ratio |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        fast = row[f"seconds_{args.spp}spp"] + row["seconds_denoise_colour"]
        slow = row[f"seconds_{more}spp"]
        lines.append(
            f"| {row['style']} | {row[f'rmse_{args.spp}spp']:.4f} | {row['rmse_denoised_colour']:.4f} | "
            f"{row['rmse_denoised_albedo']:.4f} | {row[f'rmse_{more}spp']:.4f} | {fast:.1f} s | {slow:.1f} s | "
            f"{slow / fast:.1f}x |"
        )
    if flicker:
        lines += [
            "",
            f"Sequence flicker ({flicker.get('frames', args.sequence)} held-out smoke frames from frame 69, one view, "
            "the same albedo on every frame; mean frame-to-frame change of the display image over the medium):",
            "",
            f"| {args.spp} spp | {args.spp} spp denoised |",
            "|---|---|",
            f"| {flicker['noisy']:.4f} | {flicker['denoised']:.4f} |",
        ]
    lines += [
        "",
        "`python experiments/denoise_study.py "
        + " ".join(f"--{k.replace('_', '-')} {v}" for k, v in sorted(vars(args).items()) if k != "out")
        + "`",
        "",
    ]
    path.write_text("\n".join(lines))


def write_sheet(path: Path, tiles: list, args) -> None:
    """The sequence's frames: a row per frame, at ``--spp`` undenoised and denoised."""
    from PIL import Image

    side = tiles[0][0].shape[0]
    sheet = np.ones((side * len(tiles), side * 2, 3), np.float32)
    for r, row in enumerate(tiles):
        for c, image in enumerate(row):
            sheet[r * side : (r + 1) * side, c * side : (c + 1) * side] = image
    Image.fromarray((np.clip(sheet, 0, 1) * 255 + 0.5).astype(np.uint8)).save(path, quality=92)
    print(f"sheet {path}: a row per frame; columns {args.spp} spp | denoised")


if __name__ == "__main__":
    main()
