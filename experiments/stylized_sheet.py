"""A contact sheet of the shipped network on unseen styles: style | fast layer | path traced | path traced
with the colour match, per row.

The bundled 64^3 smoke frame (never trained on) is stylized with each held-out offline style and
rendered from one orbit view with the fast layer and with ``volpath`` (multiple scattering, the
training light), first the network's albedo as predicted, then with the colour match that
``mistyle.stylize`` applies by default (``mistyle.colour_match``). PNGs use the training tone curve.

    python experiments/stylized_sheet.py --out results/stylized_sheet/stylized_unseen.jpg
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from mistyle.pages import EXPERIMENTS_TITLE, write_index


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("results/stylized_sheet/stylized_unseen.jpg"))
    parser.add_argument("--styles", type=int, default=6)
    parser.add_argument("--res", type=int, default=128)
    parser.add_argument("--spp", type=int, default=64)
    args = parser.parse_args()

    import torch

    from mistyle.api import Stylizer, display, path_trace
    from mistyle.bridge_torch import render_views
    from mistyle.files import load_density, write_jpeg
    from mistyle.integrators import prepare_density
    from mistyle.model.features import square_style
    from mistyle.scenes import CameraPath
    from mistyle.train.dataset import StyleSet

    stylizer = Stylizer()
    config = stylizer.config
    density = load_density("examples/smoke_64.vol")
    prepared = prepare_density(density, stylizer.density_scale)
    view = CameraPath(distance=config.render.camera_distance).held_out(1)
    styles = StyleSet(config.data.styles, 128)
    picks = np.linspace(0, len(styles.val) - 1, min(args.styles, len(styles.val))).round().astype(int)
    rows = []
    for index in picks:
        style = styles.val[index].permute(1, 2, 0).numpy()
        albedo = stylizer(density, style, match_colours=False)
        with torch.no_grad():
            layer = (
                render_views(
                    torch.from_numpy(albedo).permute(3, 0, 1, 2),
                    prepared,
                    view,
                    args.res,
                    radiance=config.render.radiance,
                )[0]
                .permute(1, 2, 0)
                .numpy()
            )
        traced = [
            path_trace(
                density,
                grid,
                view,
                res=args.res,
                spp=args.spp,
                density_scale=stylizer.density_scale,
                light=f"constant:{config.render.radiance}",
            )[0][0]
            for grid in (albedo, stylizer.match_colours([albedo], [density], style)[0])
        ]
        swatch = square_style(style, args.res).permute(1, 2, 0).numpy()
        rows.append(np.concatenate([swatch, display(layer)] + [display(image) for image in traced], axis=1))
        print(styles.val_names[index], flush=True)
    write_jpeg(args.out, np.concatenate(rows, axis=0), srgb=False)
    write_index(args.out.parent, EXPERIMENTS_TITLE)
    print(f"wrote {args.out} and {args.out.parent / 'index.html'}")


if __name__ == "__main__":
    main()
