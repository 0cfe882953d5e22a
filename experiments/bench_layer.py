"""Benchmark the fast layer: Mitsuba vs pure torch, and the sheared Ls precompute vs brute force.

Times, in one run on the same inputs:
  * forward + backward of V views at S^2 through an R^3 density, for the Mitsuba layer
    (``mistyle.bridge_torch.render_views``) and the pure-torch ``grid_sample`` reference;
  * the Ls precompute with the sheared sweep (as used: only where the layer can use Ls, with the
    trilinear nodes fitted to the samples as ``prepare_density`` does; the samples alone; and over
    every voxel) and with brute-force marching over every voxel, and the error that the sheared
    Ls causes in the layer's images (relative RMSE against images made with the brute-force Ls).

Prints one JSON line. Defaults are the issue's setting: 4 views at 160^2 through 64^3, N=64, K=128.

    python experiments/bench_layer.py            # full
    python experiments/bench_layer.py --quick    # small sizes, seconds
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np
import torch


def best_of(repeats: int, fn):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="32^3, 2 views at 64^2, K=32")
    parser.add_argument("--res", type=int, default=64)
    parser.add_argument("--views", type=int, default=4)
    parser.add_argument("--image", type=int, default=160)
    parser.add_argument("--steps", type=int, default=64)
    parser.add_argument("--directions", type=int, default=128)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    if args.quick:
        args.res, args.views, args.image, args.directions, args.repeats = 32, 2, 64, 32, 2

    from mistyle.backend import use_variant
    from mistyle.bridge_torch import render_views
    from mistyle.conventions import DEFAULT_DENSITY_SCALE
    from mistyle.data.procedural import pyroclastic_sphere
    from mistyle.integrators import prepare_density
    from mistyle.integrators.inscatter import inscattered_radiance
    from mistyle.reference_torch import render_views_torch
    from mistyle.scenes import CameraPath

    use_variant("cpu")
    torch.manual_seed(0)
    density = pyroclastic_sphere((args.res,) * 3, seed=1)
    scale = DEFAULT_DENSITY_SCALE
    views = CameraPath().turntable(args.views, offset=0.1)
    size = (args.image, args.image)

    # --- Ls: sheared vs brute force, warm-up runs compile the kernels first ---
    sigma_t = density * np.float32(scale)

    def sheared():
        return inscattered_radiance(sigma_t, args.directions, "sheared")

    def sheared_prepared():  # what the layer gets: the samples, then the nodes fitted to them
        return prepare_density(density, scale, args.directions, "sheared")

    def sheared_every_voxel():
        return inscattered_radiance(sigma_t, args.directions, "sheared", only_where_used=False)

    def bruteforce():
        return inscattered_radiance(sigma_t, args.directions, "bruteforce", only_where_used=False)

    for warm_up in (sheared, sheared_prepared, sheared_every_voxel, bruteforce):
        warm_up()
    ls_samples_seconds = best_of(args.repeats, sheared)
    ls_fast_seconds = best_of(args.repeats, sheared_prepared)
    ls_dense_seconds = best_of(args.repeats, sheared_every_voxel)
    ls_brute_seconds = best_of(1, bruteforce)
    fast = prepare_density(density, scale, args.directions, ls=sheared())
    brute = prepare_density(density, scale, args.directions, ls=bruteforce())

    albedo = torch.rand((1, 3) + density.shape) * 0.8 + 0.1
    with torch.no_grad():
        image_fast = render_views(albedo, fast, views, size, steps=args.steps)
        image_brute = render_views(albedo, brute, views, size, steps=args.steps)
    ls_rel_error = float(((image_fast - image_brute).pow(2).mean() / image_brute.pow(2).mean()).sqrt())

    # --- forward + backward: Mitsuba layer vs pure torch, same loss ---
    weights = torch.rand((1, args.views, 3) + size)

    def mitsuba_step():
        a = albedo.clone().requires_grad_()
        (render_views(a, fast, views, size, steps=args.steps) * weights).sum().backward()

    sigma_torch, ls_torch = torch.from_numpy(fast.sigma_t), torch.from_numpy(fast.ls)

    def torch_step():
        a = albedo.clone().requires_grad_()
        (render_views_torch(a, sigma_torch, ls_torch, views, size, steps=args.steps) * weights).sum().backward()

    mitsuba_step()  # compile
    torch_step()
    layer_seconds = best_of(args.repeats, mitsuba_step)
    torch_seconds = best_of(args.repeats, torch_step)

    print(
        json.dumps(
            {
                "speedup_vs_torch": torch_seconds / layer_seconds,
                "ls_speedup_vs_bruteforce": ls_brute_seconds / ls_fast_seconds,
                "ls_rel_error": ls_rel_error,
                "layer_fwd_bwd_seconds": layer_seconds,
                "torch_fwd_bwd_seconds": torch_seconds,
                "ls_sheared_seconds": ls_fast_seconds,
                "ls_sheared_samples_only_seconds": ls_samples_seconds,
                "ls_sheared_every_voxel_seconds": ls_dense_seconds,
                "ls_speedup_every_voxel": ls_brute_seconds / ls_dense_seconds,
                "used_voxel_fraction": float(inscatter_used_fraction(sigma_t)),
                "ls_bruteforce_seconds": ls_brute_seconds,
                "setting": {
                    "res": args.res,
                    "views": args.views,
                    "image": args.image,
                    "steps": args.steps,
                    "directions": args.directions,
                },
                "machine": {
                    "cpu_count": os.cpu_count(),
                    "torch_threads": torch.get_num_threads(),
                    "load_avg_1m": os.getloadavg()[0],
                    "platform": platform.platform(),
                },
            }
        )
    )


def inscatter_used_fraction(sigma_t) -> float:
    from mistyle.integrators.inscatter import layer_reads_ls

    return layer_reads_ls(sigma_t).mean()


if __name__ == "__main__":
    main()
