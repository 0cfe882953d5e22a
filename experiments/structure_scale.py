"""The structure-scale control (paper Sec. 5.5, its Fig. 17), as a figure at three scales (#14).

The density is resampled by a factor s before the network stylizes it and the albedo is resampled
back (``stylize(..., scale_structures=s)``, ``render_final --scale-structures s``): the network's
receptive field stays the same number of voxels, so at s = 2 it spans half as much of the volume and
the style's structures come out smaller, at s = 0.5 larger. Each row is one held-out style on the
held-out smoke64 plume at s = 0.5, 1 and 2, path traced (``volpath``, multiple scattering, the
training light) from the held-out view, above the albedo's middle slice (black where there is no
medium), where the structures' size is easier to see than through the medium.

The figure states what it shows with a number: under each tile, the albedo's correlation length,
the lag in voxels of the original grid at which the autocorrelation of the albedo's luminance
inside the medium falls to one half (``albedo_correlation_length``). The density's own correlation
length is the same in every tile, so what changes is the style's structure, not the medium's.
Also writes ``<out>.json`` with the numbers.

    python experiments/structure_scale.py --out results/structure_scale/structure_scale.jpg
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from mistyle.pages import EXPERIMENTS_TITLE, write_grid, write_index

SCALES = (0.5, 1.0, 2.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("results/structure_scale/structure_scale.jpg"))
    parser.add_argument("--checkpoint", default=None, help="default: the bundled network")
    parser.add_argument("--density", default="smoke64", help="a held-out density (mistyle.data.heldout)")
    parser.add_argument("--styles", default="hokusai_great_wave,munch_the_scream")
    parser.add_argument("--scales", default=",".join(f"{s:g}" for s in SCALES))
    parser.add_argument("--cache", default="data/heldout", help="where held-out densities are cached")
    parser.add_argument("--res", type=int, default=160)
    parser.add_argument("--spp", type=int, default=32)
    args = parser.parse_args()
    scales = [float(s) for s in args.scales.split(",")]

    from mistyle.api import Stylizer, display, path_trace
    from mistyle.conventions import HELD_OUT_VIEW
    from mistyle.data.heldout import (
        HELD_OUT_DENSITIES,
        held_out_density,
        held_out_styles,
    )
    from mistyle.files import load_style
    from mistyle.model.features import square_style
    from mistyle.objective.metrics import correlation_length
    from mistyle.scenes import CameraPath

    stylizer = Stylizer(args.checkpoint)
    config = stylizer.config
    specs = {spec.name: spec for spec in HELD_OUT_DENSITIES}
    if args.density not in specs:
        parser.error(f"--density {args.density!r} is not a held-out density; choose one of {sorted(specs)}")
    density = held_out_density(specs[args.density], args.cache)
    view = [CameraPath(distance=config.render.camera_distance).view(HELD_OUT_VIEW)]
    records = held_out_styles()
    density_length = correlation_length(density, density > 0)
    rows, numbers = [], []
    for name in args.styles.split(","):
        style = load_style(records[name]["path"])
        row = [(square_style(style, args.res).permute(1, 2, 0).numpy(), name[:20])]
        slices = [(np.zeros((args.res, args.res, 3), np.float32), "albedo, middle slice")]
        for scale in scales:
            albedo = stylizer(density, style, scale_structures=scale)
            length = albedo_correlation_length(albedo, density)
            image = path_trace(
                density,
                albedo,
                view,
                res=args.res,
                spp=args.spp,
                density_scale=stylizer.density_scale,
                light=f"constant:{config.render.radiance}",
            )[0][0]
            row.append((display(image), f"s={scale:g}: albedo {length:.1f} vox"))
            slices.append((middle_slice(albedo, density), f"s={scale:g}"))
            numbers.append(
                {
                    "style": name,
                    "scale": scale,
                    "albedo_correlation_length": length,
                    "density_correlation_length": density_length,
                }
            )
            print(json.dumps(numbers[-1]), flush=True)
        rows += [row, slices]
    write_grid(args.out, rows, args.res)
    args.out.with_suffix(".json").write_text(json.dumps({"density": args.density, "results": numbers}, indent=1) + "\n")
    write_index(args.out.parent, EXPERIMENTS_TITLE)
    print(f"wrote {args.out} and {args.out.with_suffix('.json')} (density correlation length {density_length:.1f} vox)")


def middle_slice(albedo: np.ndarray, density: np.ndarray) -> np.ndarray:
    """The albedo on the grid's middle plane across its first axis, ``(Y, X, 3)`` in display space,
    black where the density is zero, the grid's last rows at the top."""
    from mistyle.files import linear_to_srgb

    middle = albedo.shape[0] // 2
    plane = np.where(density[middle, ..., None] > 0, albedo[middle], 0.0)
    return linear_to_srgb(plane[::-1])


def albedo_correlation_length(albedo: np.ndarray, density: np.ndarray) -> float:
    """``correlation_length`` of the luminance of ``albedo (Z, Y, X, 3)`` where ``density > 0``."""
    from mistyle.objective.metrics import correlation_length
    from mistyle.stylizer import LUMA_WEIGHTS

    return correlation_length(np.asarray(albedo, np.float64) @ LUMA_WEIGHTS, density > 0)


if __name__ == "__main__":
    main()
