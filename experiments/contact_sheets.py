"""Contact sheets of mistyle's generated data: densities rendered with the fast layer, and styles.

    python experiments/contact_sheets.py --out results/contact_sheets

writes ``contact_densities.jpg`` (smoke plumes at three times, fire, pyroclastic sphere,
noise-filled level set, spot noise, voxelized mesh; white albedo, constant light) and
``contact_styles.jpg`` (the offline default style set).
"""

from __future__ import annotations

import argparse
from collections import deque
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from mistyle.pages import EXPERIMENTS_TITLE, write_index


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("results") / "contact_sheets")
    parser.add_argument("--res", type=int, default=64)
    parser.add_argument("--image", type=int, default=128)
    args = parser.parse_args()
    torch.set_flush_denormal(True)

    from mistyle.backend import use_variant
    from mistyle.data.mesh import icosphere, voxelize
    from mistyle.data.procedural import (
        noise_filled_level_set,
        pyroclastic_sphere,
        spot_noise,
        torus_sdf,
    )
    from mistyle.data.smoke import FireConfig, PlumeConfig, simulate
    from mistyle.data.styles import offline_style_set
    from mistyle.files import write_jpeg
    from mistyle.integrators import layer_scene, prepare_density
    from mistyle.scenes import View, split_views

    mi = use_variant("cpu")
    shape = (args.res,) * 3
    densities = []
    rng = np.random.default_rng(1)
    for plume in range(3):
        config = PlumeConfig.random(shape, rng)
        for frame, density, _ in simulate(config, 90, seed=plume):
            if frame + 1 in (40, 65, 90):
                densities.append(density)
    _, density, _ = deque(simulate(FireConfig(resolution=shape, source_radius=0.1), 60, seed=0), maxlen=1)[0]
    densities.append(density)  # the last frame
    densities.append(pyroclastic_sphere(shape, seed=3))
    densities.append(noise_filled_level_set(torus_sdf(shape), seed=1))
    vertices, faces = icosphere(3)
    densities.append(spot_noise(vertices, faces, args.res, impulses=3000, seed=2))
    densities.append(voxelize(vertices * np.array([1.0, 0.6, 0.8]), faces, args.res, supersample=2))

    view = View(origin=(0.0, 0.4, 2.4))
    tiles = []
    for density in densities:
        prepared = prepare_density(density, 30.0)
        albedo = np.full(density.shape + (3,), 0.9, np.float32)
        scene = mi.load_dict(layer_scene(prepared, albedo, [view], res=args.image))
        tiles.append(split_views(mi.render(scene), 1)[0])
    columns = 4
    while len(tiles) % columns:
        tiles.append(np.zeros_like(tiles[0]))
    rows = [np.concatenate(tiles[i : i + columns], axis=1) for i in range(0, len(tiles), columns)]
    write_jpeg(args.out / "contact_densities.jpg", np.concatenate(rows, axis=0) * 1.5)

    styles = [image for _, image in offline_style_set(size=64)]
    columns = 16
    while len(styles) % columns:
        styles.append(np.zeros_like(styles[0]))
    rows = [np.concatenate(styles[i : i + columns], axis=1) for i in range(0, len(styles), columns)]
    # JPEG: the sheet of 300-odd photographs is 0.76 MB as PNG, a quarter of that as JPEG at quality 90.
    sheet = (np.concatenate(rows, axis=0).clip(0, 1) * 255 + 0.5).astype(np.uint8)
    Image.fromarray(sheet).save(args.out / "contact_styles.jpg", quality=90)
    write_index(args.out, EXPERIMENTS_TITLE)
    print(f"wrote {args.out}/contact_densities.jpg, {args.out}/contact_styles.jpg and {args.out}/index.html")


if __name__ == "__main__":
    main()
