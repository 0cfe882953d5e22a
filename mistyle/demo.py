"""``python -m mistyle.demo``: the bundled example volume through the fast layer and the path tracer.

Until the stylization network exists this is the main job: it renders the bundled smoke frame
``examples/smoke_64.vol`` with a procedural colour albedo from three views on the training orbit with
  1. the fast layer (single scattering, the training renderer),
  2. Mitsuba's ``volpath`` with ``max_depth=2`` (single scattering, the layer's reference),
  3. ``volpath`` with full multiple scattering (what final renders look like),
and writes linear EXR and sRGB PNG images plus ``comparison.png`` (rows in that order).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "smoke_64.vol"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(prog="python -m mistyle.demo", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--density", type=Path, default=EXAMPLE, help=".vol or .npy density (Z, Y, X)")
    parser.add_argument("--out", type=Path, default=Path("out/demo"))
    parser.add_argument("--res", type=int, default=160, help="image size in pixels")
    parser.add_argument("--views", type=int, default=3)
    parser.add_argument("--spp", type=int, default=64, help="path tracer samples per pixel")
    parser.add_argument("--density-scale", type=float, default=None)
    args = parser.parse_args(argv)

    from .backend import use_variant
    from .data.procedural import colour_noise_albedo
    from .io import write_exr, write_png
    from .scenes import (
        DEFAULT_DENSITY_SCALE,
        CameraPath,
        layer_scene,
        pathtraced_scene,
        prepare_density,
        split_views,
    )
    from .volume import load_density

    mi = use_variant("cpu")
    scale = DEFAULT_DENSITY_SCALE if args.density_scale is None else args.density_scale
    density = load_density(args.density)
    albedo = colour_noise_albedo(density.shape, seed=11)
    views = CameraPath().turntable(args.views, offset=0.125)
    size = (args.res, args.res)
    timings = {}

    start = time.perf_counter()
    prepared = prepare_density(density, scale)
    timings["ls_seconds"] = time.perf_counter() - start

    def timed(name, scene_dict):
        scene = mi.load_dict(scene_dict)
        start = time.perf_counter()
        images = split_views(mi.render(scene), len(views))
        timings[f"{name}_seconds"] = time.perf_counter() - start
        return images

    rows = {
        "layer": timed("layer", layer_scene(prepared, albedo, views, *size)),
        "pathtraced_single": timed(
            "pathtraced_single", pathtraced_scene(density, scale, albedo, views, *size, spp=args.spp, max_depth=2)
        ),
        "pathtraced_multi": timed(
            "pathtraced_multi", pathtraced_scene(density, scale, albedo, views, *size, spp=args.spp, max_depth=-1)
        ),
    }

    out = args.out
    for name, images in rows.items():
        for index, image in enumerate(images):
            write_exr(out / f"{name}_view{index}.exr", image)
            write_png(out / f"{name}_view{index}.png", image)
    # One exposure for the whole sheet, so the rows compare directly.
    sheet = np.concatenate([np.concatenate(list(images), axis=1) for images in rows.values()], axis=0)
    exposure = 0.8 / max(float(np.percentile(sheet, 99.5)), 1e-6)
    write_png(out / "comparison.png", sheet * exposure)
    summary = {"density": str(args.density), "shape_zyx": list(density.shape), "density_scale": scale,
               "views": args.views, "image": args.res, "spp": args.spp, **timings}
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(summary))
    print(f"Wrote {out}/comparison.png (rows: fast layer, path-traced single scattering, "
          f"path-traced multiple scattering) and per-view EXR/PNG files in {out}/")


if __name__ == "__main__":
    main()
