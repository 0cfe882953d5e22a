"""The style-strength and style-mixing figure: what ``--strength`` and ``--mix`` do to a render.

Row 1: the bundled smoke stylized with one held-out painting at strengths 0, 0.25, 0.5, 0.75 and 1
(``Stylizer.weakened``: the last stylizing kernel blended towards the one that makes a uniform grey
of the styled medium's brightness). Row 2: a mix of two held-out paintings at weights 1:0, 0.75:0.25,
0.5:0.5, 0.25:0.75 and 0:1 (``StylizingKernels.blend`` of their predicted kernels). The style pictures
(or the mix's mosaic, ``style.style_target``) sit at the left and right ends; each tile is the
network's albedo as predicted, path traced with ``volpath`` (multiple scattering, training light),
with its RGB SWD to the row's full style printed on it. Also writes ``<out>.json`` with the numbers.

    python experiments/strength_mix.py --out results/strength_mix/strength_mix.jpg
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from mistyle.pages import EXPERIMENTS_TITLE, write_grid, write_index

LEVELS = (0.0, 0.25, 0.5, 0.75, 1.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("results/strength_mix/strength_mix.jpg"))
    parser.add_argument("--styles", default="hokusai_great_wave,van_gogh_starry_night")
    parser.add_argument("--res", type=int, default=128)
    parser.add_argument("--spp", type=int, default=32)
    args = parser.parse_args()

    from mistyle.api import Stylizer, display, path_trace
    from mistyle.data.heldout import held_out_styles
    from mistyle.files import load_density, load_style
    from mistyle.model.features import square_style
    from mistyle.objective.metrics import style_fidelity
    from mistyle.scenes import CameraPath
    from mistyle.style import style_target

    stylizer = Stylizer()
    config = stylizer.config
    density = load_density("examples/smoke_64.vol")
    view = [CameraPath(distance=config.render.camera_distance).view(0.1)]
    records = held_out_styles()
    first, second = (load_style(records[name]["path"]) for name in args.styles.split(","))

    def tile(albedo, target):
        image = path_trace(
            density,
            albedo,
            view,
            res=args.res,
            spp=args.spp,
            density_scale=stylizer.density_scale,
            light=f"constant:{config.render.radiance}",
        )[0][0]
        return display(image), style_fidelity([image], target)

    def swatch(style):
        return square_style(style, args.res).permute(1, 2, 0).numpy()

    rows, numbers = [], {"strength": [], "mix": []}
    strength_tiles = []
    for level in LEVELS:
        shown, metrics = tile(stylizer(density, first, strength=level), first)
        strength_tiles.append((shown, f"s={level:g}: RGB SWD {metrics['rgb_swd']:.3f}"))
        numbers["strength"].append({"strength": level, **metrics})
    rows.append([(swatch(first), "style")] + strength_tiles + [(swatch(first), "style")])
    mix_tiles = []
    for weight in LEVELS:
        mix = [(first, 1.0 - weight), (second, weight)]
        target = style_target([first, second], [1.0 - weight, weight])
        shown, metrics = tile(stylizer(density, mix), target)
        mix_tiles.append((shown, f"{1 - weight:g}:{weight:g}: RGB SWD {metrics['rgb_swd']:.3f}"))
        numbers["mix"].append({"weights": [1.0 - weight, weight], **metrics})
    rows.append([(swatch(first), "style A")] + mix_tiles + [(swatch(second), "style B")])

    write_grid(args.out, rows, args.res)
    args.out.with_suffix(".json").write_text(json.dumps(numbers, indent=1) + "\n")
    write_index(args.out.parent, EXPERIMENTS_TITLE)
    print(json.dumps(numbers))
    print(f"wrote {args.out} and {args.out.with_suffix('.json')}")


if __name__ == "__main__":
    main()
