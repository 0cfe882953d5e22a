"""A contact sheet of benchmark tiles from several runs side by side: one row per (density, style), one
column per run and method, the style first, each tile enlarged so that strokes can be seen.

    python experiments/before_after_sheet.py --out results/look_production_sizes/sheet_real.jpg \\
        --densities wdas_cloud,usd_plume,openvdb_smoke --styles hokusai_great_wave,munch_the_scream \\
        --column before=BEFORE/tiles:default --column after=AFTER/tiles:default \\
        --column tuned_noise=BEFORE/tiles:tuned_noise --column uniform=BEFORE/tiles:uniform

Each ``--column LABEL=TILES:METHOD`` reads ``TILES/<density>__<style>__<METHOD>.png`` (``mistyle-bench``'s
``tiles/``, which the benchmark writes and does not commit).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from PIL import Image, ImageDraw

STYLES_DIR = Path(__file__).resolve().parents[1] / "mistyle" / "data" / "heldout_styles"
HEADER = 20


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--densities", required=True, help="comma-separated density names")
    parser.add_argument("--styles", required=True, help="comma-separated held-out style names")
    parser.add_argument("--column", action="append", required=True, help="LABEL=TILES_FOLDER:METHOD")
    parser.add_argument("--side", type=int, default=192, help="each tile's side in the sheet")
    args = parser.parse_args(argv)
    columns = []
    for item in args.column:
        label, rest = item.split("=", 1)
        folder, method = rest.rsplit(":", 1)
        columns.append((label, Path(folder), method))
    pairs = [(d, s) for d in args.densities.split(",") for s in args.styles.split(",")]
    side = args.side
    sheet = Image.new("RGB", (side * (len(columns) + 1), HEADER + side * len(pairs)), "white")
    draw = ImageDraw.Draw(sheet)
    for index, label in enumerate(["style"] + [label for label, _, _ in columns]):
        draw.text((index * side + 4, 4), label, fill="black")
    for row, (density, style) in enumerate(pairs):
        top = HEADER + row * side
        picture = Image.open(next(STYLES_DIR.glob(f"{style}.*"))).convert("RGB")
        picture.thumbnail((side, side))
        sheet.paste(picture, (0, top))
        for index, (_, folder, method) in enumerate(columns, 1):
            tile = Image.open(folder / f"{density}__{style}__{method}.png").convert("RGB")
            sheet.paste(tile.resize((side, side), Image.LANCZOS), (index * side, top))
        draw.text((4, top + side - 14), density, fill="red")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(args.out, quality=85)
    print(f"wrote {args.out} ({sheet.size[0]}x{sheet.size[1]})")


if __name__ == "__main__":
    main()
