"""Where the fast layer's error against the path tracer comes from.

One pixel-centre ``volpath`` reference (max_depth=2, two seeds, noise taken out; see
``layer_vs_pathtraced.py``), then the layer with one ingredient changed at a time:
  * K, the number of directions for Ls, and the Ls method (sheared or brute force);
  * N, the number of ray-marching steps;
  * what the Ls texture holds: the Ls samples at its voxel centres (``samples``, as in the paper)
    or the nodes fitted to them for trilinear interpolation (``nodes``, ``inscatter.trilinear_nodes``,
    what ``prepare_density`` gives the layer);
  * where rays are marched: the whole medium box (``box``) or the extinction's support
    (``support``, ``MediumBox.field_support``, the layer's default);
  * the resolution of the Ls grid (1x: the density's own grid, as in the paper; 2x or 3x: a finer
    grid, sheared on the resampled extinction, or brute force from the same trilinear extinction;
    only on the 3x grid is the resampled extinction exactly the rendered field).

Prints one JSON line: ``{"noise": ..., "rows": [{"K", "method", "ls_grid", "ls", "march", "N", "rel_rmse",
"brightness"}]}``.

    python experiments/layer_error_budget.py   # 64^3 pyroclastic sphere, 2 views at 128^2, 2 x 8192 spp (~15 min)
    python experiments/layer_error_budget.py --density data/heldout/smoke64.npy --reference-cache runs/smoke64_ref.npz
    python experiments/layer_error_budget.py --quick    # 24^3, 32^2
"""

from __future__ import annotations

import argparse
import json
import os

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--density", default=None, help="a (Z, Y, X) .npy density instead of the pyroclastic sphere")
    parser.add_argument(
        "--reference-cache",
        default=None,
        help="an .npz to load the path-traced reference from, or to save it to when missing",
    )
    args = parser.parse_args()
    res, image, spp = (24, 32, 1024) if args.quick else (64, 128, 8192)

    from mistyle.backend import use_variant
    from mistyle.conventions import DEFAULT_DENSITY_SCALE
    from mistyle.data.procedural import colour_noise_albedo, pyroclastic_sphere
    from mistyle.integrators import PreparedDensity, layer_scene, prepare_density
    from mistyle.integrators.inscatter import (
        inscattered_radiance,
        inscattered_radiance_at,
        layer_reads_ls,
    )
    from mistyle.pathtrace import (
        net_rel_rmse,
        pixel_centre_estimate,
        two_seed_reference,
    )
    from mistyle.scenes import CameraPath, pathtraced_scene, split_views

    mi = use_variant("cpu")
    scale = DEFAULT_DENSITY_SCALE
    density = (
        pyroclastic_sphere((res,) * 3, seed=7) if args.density is None else np.load(args.density).astype(np.float32)
    )
    albedo = colour_noise_albedo(density.shape, seed=11)
    views = CameraPath().turntable(2, offset=0.125)
    sigma_t = density * np.float32(scale)
    if args.reference_cache and os.path.isfile(args.reference_cache):
        cached = np.load(args.reference_cache)
        reference, noise = cached["reference"], float(cached["noise"])
    else:
        reference_scene = mi.load_dict(
            pathtraced_scene(density, albedo, views, res=image, density_scale=scale, max_depth=2, batch=True)
        )
        reference, noise = two_seed_reference(
            lambda count, seed: pixel_centre_estimate(reference_scene, count, seed, 2), spp
        )
        if args.reference_cache:
            np.savez(args.reference_cache, reference=reference, noise=noise)

    def layer(ls: np.ndarray, steps: int, march: str) -> np.ndarray:
        scene = layer_scene(PreparedDensity(density, scale, np.ones_like(ls)), albedo, views, res=image, steps=steps)
        scene["integrator"]["ls"] = mi.TensorXf(np.ascontiguousarray(ls, dtype=np.float32)[..., None])
        if march == "box":
            scene["integrator"]["march_min"] = scene["integrator"]["bbox_min"]
            scene["integrator"]["march_max"] = scene["integrator"]["bbox_max"]
        return split_views(mi.render(mi.load_dict(scene)), 2)

    def nodes(ls: np.ndarray) -> np.ndarray:
        return prepare_density(density, scale, ls=ls).ls  # what the layer gets for these samples

    def fine_ls(factor: int, directions: int) -> np.ndarray:
        used = layer_reads_ls(sigma_t)
        for axis in range(3):
            used = np.repeat(used, factor, axis=axis)
        z, y, x = np.nonzero(used)
        ls = np.ones(used.shape, dtype=np.float32)
        ls[used] = inscattered_radiance_at(sigma_t, (np.stack([x, y, z], axis=1) + 0.5) / factor, directions)
        return ls

    grids = {
        (128, "sheared", 1): inscattered_radiance(sigma_t, 128, "sheared"),
        (128, "bruteforce", 1): inscattered_radiance(sigma_t, 128, "bruteforce"),
        (2048, "sheared", 1): inscattered_radiance(sigma_t, 2048, "sheared"),
        (128, "sheared", 2): inscattered_radiance(sigma_t, 128, "sheared", grid_factor=2),
        (128, "sheared", 3): inscattered_radiance(sigma_t, 128, "sheared", grid_factor=3),
        (128, "bruteforce", 2): fine_ls(2, 128),
    }
    rows = []
    for (directions, method, factor), samples in grids.items():
        fitted = nodes(samples)
        for ls, march in (("samples", "box"), ("samples", "support"), ("nodes", "box"), ("nodes", "support")):
            for steps in (64, 80, 128, 256):
                rendered = layer(samples if ls == "samples" else fitted, steps, march)
                rows.append(
                    {
                        "K": directions,
                        "method": method,
                        "ls_grid": factor,
                        "ls": ls,
                        "march": march,
                        "N": steps,
                        "rel_rmse": net_rel_rmse(rendered, reference, noise),
                        "brightness": float(rendered.mean() / reference.mean()),
                    }
                )
    print(
        json.dumps({"noise": float(np.sqrt(noise / np.mean(reference**2))), "res": res, "image": image, "rows": rows})
    )


if __name__ == "__main__":
    main()
