"""The style-fidelity benchmark: how much of a style reaches the path-traced medium (DESIGN.md,
"Measuring style fidelity"), on styles and densities that training never saw (``mistyle.data.heldout``).

For every (held-out density, held-out style) pair, four methods, each through the path a user takes:

* ``network``: ``api.Stylizer`` alone (``render_final --refine 0``): the network's arrangement with the
  style's colours (``mistyle.colour_match``), or with ``--no-colour-match`` the network's albedo as
  predicted (rows before the colour match, e.g. ``network@b8``, are the latter);
* ``final``: ``python -m mistyle.render_final`` at its defaults (run in-process; its refined albedo);
* ``uniform``: the must-beat baseline, one colour whose path-traced mean matches the style's
  (``correct.matched_uniform_albedo``);
* ``optimised``: the upper reference, direct optimisation of the albedo grid from the baseline's
  with render_final's refinement at ``--optimise-factor`` times its steps (``--methods`` can leave it
  out where it is too slow, e.g. at 128^3).

Each albedo is path traced from 3 views around the orbit and scored with
``objective.metrics.style_fidelity`` (RGB SWD, patch SWD, hue coverage). The ``seconds`` of ``final``
are render_final's for the frame (stylize + refine + one --res^2 path-traced view at 64 spp).

    python experiments/style_fidelity.py                           # 14 styles x 3 densities: about 2 h on 2 cores
    python experiments/style_fidelity.py --densities smoke64 --styles hokusai_great_wave,munch_the_scream
    python experiments/style_fidelity.py --quick                   # 1 pair, small renders, few steps
    python experiments/style_fidelity.py --methods network,final --checkpoint runs/x/final.pt --label x --resume
        # another network beside the rows already there: its methods are named network@x, final@x
Writes ``docs/style_fidelity.jsonl`` (a line per density, style, method), ``docs/style_fidelity_table.md``
(medians per method) and ``docs/style_fidelity_sheet.jpg`` (style | network | final | uniform | optimised).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from mistyle.pages import EXPERIMENTS_TITLE, write_index

sys.path.insert(0, str(Path(__file__).resolve().parent))

METHODS = ("network", "final", "uniform", "optimised")
DEFAULT_DENSITIES = "smoke64,smoke128,pyroclastic64"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--densities", default=DEFAULT_DENSITIES, help="names in mistyle.data.heldout (rock64 too)")
    parser.add_argument("--styles", default="all", help="comma-separated held-out style names, or all")
    parser.add_argument("--res", type=int, default=256, help="render_final --res and the metric renders")
    parser.add_argument("--spp", type=int, default=16, help="paths per pixel of the metric renders")
    parser.add_argument("--methods", default=",".join(METHODS), help="a subset of " + ", ".join(METHODS))
    parser.add_argument("--optimise-factor", type=float, default=2)
    parser.add_argument("--checkpoint", default=None, help="SKPN checkpoint for network and final (default: the bundled one)")
    parser.add_argument("--label", default="", help="suffix of the method names of this checkpoint's rows (network@LABEL)")
    parser.add_argument("--no-colour-match", dest="colour_match", action="store_false",
                        help="network and final without the colour match (render_final --no-colour-match)")
    parser.add_argument("--out", default="docs/style_fidelity")
    parser.add_argument("--cache", default="data/heldout", help="where held-out densities are cached")
    parser.add_argument("--resume", action="store_true", help="skip pairs already in <out>.jsonl")
    parser.add_argument("--report-only", action="store_true", help="rewrite the table and sheet from <out>.jsonl")
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    if args.quick:
        args.densities, args.styles, args.res, args.spp, args.optimise_factor = "pyroclastic64", "hokusai_great_wave", 32, 4, 1
        args.out = str(Path(tempfile.mkdtemp()) / "style_fidelity")

    import torch

    from fidelity_core import metric_views, score, uniform_baseline
    from mistyle.api import Stylizer
    from mistyle.data.heldout import HELD_OUT_DENSITIES, held_out_density, held_out_styles
    from mistyle.io import load_style, write_npy
    from mistyle.fit import refine_albedo
    from mistyle.integrators import prepare_density
    from mistyle.render_final import refinement_settings

    torch.manual_seed(0)
    stylizer = Stylizer(args.checkpoint)
    config = stylizer.config
    scale, radiance = stylizer.density_scale, config.render.radiance
    views = metric_views(config.render.camera_distance)
    specs = {spec.name: spec for spec in HELD_OUT_DENSITIES}
    all_styles = held_out_styles()
    style_names = list(all_styles) if args.styles == "all" else args.styles.split(",")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    jsonl = out.with_suffix(".jsonl")
    rows = [json.loads(line) for line in jsonl.read_text().splitlines()] if args.resume and jsonl.exists() else []
    methods = [m for m in METHODS if m in args.methods.split(",")]
    named = {m: labelled(m, args.label) for m in methods}
    found: dict = {}
    for r in rows:
        found.setdefault((r["density"], r["style"]), set()).add(r["method"])
    done = {pair for pair, have in found.items() if have >= set(named.values())}
    rows = [r for r in rows if (r["density"], r["style"]) in done or r["method"] not in named.values()]
    # The contact sheet's images, kept across --resume (a --quick run keeps its own).
    tiles = (out.parent if args.quick else Path(args.cache)) / "tiles"
    if args.report_only:
        rows = [json.loads(line) for line in jsonl.read_text().splitlines()]
        write_table(rows, out.parent / f"{out.name}_table.md")
        write_sheet(rows, tiles, all_styles, out.parent / f"{out.name}_sheet.jpg")
        write_index(out.parent, EXPERIMENTS_TITLE)
        return
    jsonl.write_text("".join(json.dumps(r) + "\n" for r in rows))
    for density_name in args.densities.split(","):
        density = held_out_density(specs[density_name], args.cache)
        prepared = prepare_density(density, scale) if "optimised" in methods else None  # Ls once per density
        density_path = Path(args.cache) / f"{density_name}.npy"
        if not density_path.exists():
            write_npy(density_path, density)
        for style_name in style_names:
            if (density_name, style_name) in done:
                continue
            style_path = all_styles[style_name]["path"]
            style = load_style(style_path)
            albedos, extra = {}, {}
            started = time.perf_counter()
            albedos["network"] = stylizer(density, style, match_colours=args.colour_match)
            extra["network"] = {"seconds": time.perf_counter() - started}
            if "final" in methods:
                albedos["final"], extra["final"] = final_albedo(density_path, style_path, args)
            if "uniform" in methods or "optimised" in methods:
                started = time.perf_counter()
                albedos["uniform"] = uniform_baseline(density, style, views, density_scale=scale, radiance=radiance)
                extra["uniform"] = {"seconds": time.perf_counter() - started}
            if "optimised" in methods:
                started = time.perf_counter()
                settings = refinement_settings(config).scaled(args.optimise_factor / (37.5 if args.quick else 1))
                albedos["optimised"], _ = refine_albedo(density, scale, albedos["uniform"], style, settings, radiance=radiance,
                                                        prepared=prepared)
                extra["optimised"] = {"seconds": time.perf_counter() - started}
            for method in methods:
                metrics, images = score(density, albedos[method], style, views, res=args.res, spp=args.spp,
                                        density_scale=scale, radiance=radiance)
                row = {"density": density_name, "style": style_name, "method": named[method], **metrics, **extra[method]}
                print(json.dumps(row), flush=True)
                with jsonl.open("a") as handle:
                    handle.write(json.dumps(row) + "\n")
                rows.append(row)
                save_tile(tiles, density_name, style_name, named[method], images[0])
    write_table(rows, out.parent / f"{out.name}_table.md")
    write_sheet(rows, tiles, all_styles, out.parent / f"{out.name}_sheet.jpg")
    write_index(out.parent, EXPERIMENTS_TITLE)


def labelled(method: str, label: str) -> str:
    """A method's name in the rows: ``network``, or ``network@label`` for another checkpoint's."""
    return f"{method}@{label}" if label else method


def final_albedo(density_path: Path, style_path: Path, args) -> tuple[np.ndarray, dict]:
    """render_final at its defaults (in-process) on one pair: its (refined) albedo and its seconds."""
    from mistyle import render_final
    from mistyle.io import read_vol

    with tempfile.TemporaryDirectory() as folder:
        run_out = Path(folder) / "run"
        started = time.perf_counter()
        argv = ["--density", str(density_path), "--style", str(style_path), "--out", str(run_out), "--res", str(args.res)]
        if args.checkpoint:
            argv += ["--checkpoint", str(args.checkpoint)]
        if not args.colour_match:
            argv += ["--no-colour-match"]
        if args.quick:
            argv += ["--spp", "4", "--refine", "4", "--refine-path", "1"]
        if render_final.main(argv) != 0:
            raise SystemExit(f"render_final failed on {density_path.stem} / {style_path.stem}")
        report = json.loads((run_out / "report.json").read_text())
        refined = run_out / "albedo_refined.vol"
        albedo = read_vol(refined) if refined.exists() else np.load(run_out / "albedo.npy")
        seconds = {"seconds": report["stylize_seconds"] + report.get("refine_seconds", 0.0) + report["render_seconds_per_image"],
                   "wall_seconds": time.perf_counter() - started}
    return albedo, seconds


def methods_in(rows) -> list[str]:
    """The method names in ``rows``: the base methods' order, labelled ones after their base."""
    names = list(dict.fromkeys(r["method"] for r in rows))
    return sorted(names, key=lambda name: (METHODS.index(name.partition("@")[0]), name))


def medians(rows) -> dict:
    """Per method: medians of the metrics and of each metric's ratio to the uniform baseline's."""
    baseline = {(r["density"], r["style"]): r for r in rows if r["method"] == "uniform"}
    result = {}
    for method in methods_in(rows):
        mine = [r for r in rows if r["method"] == method and (r["density"], r["style"]) in baseline]
        if not mine:
            continue
        entry = {key: float(np.median([r[key] for r in mine])) for key in ("rgb_swd", "patch_swd", "hue_coverage", "seconds")}
        for key in ("rgb_swd", "patch_swd"):
            entry[f"{key}_ratio"] = float(np.median([r[key] / baseline[(r["density"], r["style"])][key] for r in mine]))
        entry["pairs"] = len(mine)
        result[method] = entry
    return result


def write_table(rows, path: Path) -> None:
    lines = ["| method | RGB SWD | x uniform | patch SWD | x uniform | hue coverage | seconds | pairs |",
             "|---|---|---|---|---|---|---|---|"]
    for method, m in medians(rows).items():
        lines.append(f"| {method} | {m['rgb_swd']:.4f} | {m['rgb_swd_ratio']:.2f} | {m['patch_swd']:.4f} | "
                     f"{m['patch_swd_ratio']:.2f} | {m['hue_coverage']:.2f} | {m['seconds']:.1f} | {m['pairs']} |")
    path.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


TILE = 128


def save_tile(folder: Path, density_name: str, style_name: str, method: str, image: np.ndarray) -> None:
    """The first metric view of one result, on display, as a ``TILE``^2 PNG for the contact sheet."""
    from PIL import Image

    from mistyle.display import display
    from mistyle.io import write_png

    shown = Image.fromarray((display(image) * 255 + 0.5).astype(np.uint8)).resize((TILE, TILE), Image.LANCZOS)
    folder.mkdir(parents=True, exist_ok=True)
    write_png(folder / f"{density_name}__{style_name}__{method}.png", np.asarray(shown, np.float32) / 255, srgb=False)


def write_sheet(rows, folder: Path, styles: dict, path: Path) -> None:
    """One row per (density, style) in ``rows``: the style, then each method's tile (grey when missing)."""
    from PIL import Image, ImageDraw

    from mistyle.io import atomic_output, load_style
    from mistyle.model.features import square_style

    pairs = list(dict.fromkeys((r["density"], r["style"]) for r in rows))
    if not pairs:
        return
    methods = methods_in(rows)
    canvas = np.full((len(pairs) * TILE + 16, (len(methods) + 1) * TILE, 3), 1.0, np.float32)
    for row, (density_name, style_name) in enumerate(pairs):
        tiles = [square_style(load_style(styles[style_name]["path"]), TILE).permute(1, 2, 0).numpy()]
        for method in methods:
            tile = folder / f"{density_name}__{style_name}__{method}.png"
            tiles.append(load_style(tile) if tile.exists() else np.full((TILE, TILE, 3), 0.5, np.float32))
        canvas[16 + row * TILE:16 + (row + 1) * TILE] = np.concatenate(tiles, axis=1)
    image = Image.fromarray((canvas * 255 + 0.5).astype(np.uint8))
    draw = ImageDraw.Draw(image)
    for column, name in enumerate(["style"] + methods):
        draw.text((column * TILE + 4, 2), name, fill="black")
    for row, (density_name, _) in enumerate(pairs):
        draw.text((4, 16 + row * TILE + 4), density_name, fill="white")
    with atomic_output(path) as temporary:  # JPEG: a 30-row sheet is 2 MB as PNG, 0.4 MB here
        image.save(temporary, format="JPEG", quality=88)


if __name__ == "__main__":
    main()
