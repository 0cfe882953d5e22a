"""How close is the fast layer to Mitsuba's path tracer, and what would the path tracer need to match it?

Renders one density and albedo (same box, scale, cameras and environment) with
  * the fast layer (every scheme; the default one is reported as "the layer"),
  * ``volpath`` with ``max_depth=2`` (single scattering, the layer's model) at high spp, twice
    with different seeds, so the reference's own noise can be measured and taken out:
    ``rel_rmse = sqrt(max(0, MSE(layer, ref) - noise_var(ref))) / RMS(ref)``,
  * ``volpath`` at 1, 2, 4, ... spp until its own (net) error reaches the layer's,
  * ``volpath`` with ``max_depth=-1`` (multiple scattering, the final render's model).

Prints one JSON line (keys ``rel_rmse_single``, ``rel_rmse_multi``, ``pt_spp_equal_error``,
``pt_seconds_equal_error``, ``layer_seconds`` and per-scheme details).

    python experiments/layer_vs_pathtraced.py            # 64^3, N=64, K=128, 2 views at 128^2
    python experiments/layer_vs_pathtraced.py --quick    # 24^3, 32^2, about a minute
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--res", type=int, default=64)
    parser.add_argument("--image", type=int, default=128)
    parser.add_argument("--views", type=int, default=2)
    parser.add_argument("--steps", type=int, default=64)
    parser.add_argument("--directions", type=int, default=128)
    parser.add_argument("--density-scale", type=float, default=20.0)
    parser.add_argument("--ref-spp", type=int, default=4096, help="spp of each single-scattering reference")
    parser.add_argument("--multi-spp", type=int, default=1024, help="spp of each multiple-scattering reference")
    args = parser.parse_args()
    if args.quick:
        args.res, args.image, args.ref_spp, args.multi_spp, args.directions = 24, 32, 1024, 256, 64

    from mistyle.backend import use_variant
    from mistyle.data.procedural import colour_noise_albedo, pyroclastic_sphere
    from mistyle.integrators import DEFAULT_SCHEME, SCHEMES
    from mistyle.scenes import CameraPath, layer_scene, pathtraced_scene, prepare_density, split_views

    mi = use_variant("cpu")
    density = pyroclastic_sphere((args.res,) * 3, seed=7)
    albedo = colour_noise_albedo(density.shape, seed=11)
    views = CameraPath().turntable(args.views, offset=0.125)
    size = (args.image, args.image)

    def path_trace(spp: int, max_depth: int, seed: int):
        scene = mi.load_dict(
            pathtraced_scene(density, args.density_scale, albedo, views, *size, spp=spp, max_depth=max_depth, seed=seed)
        )
        start = time.perf_counter()
        image = split_views(mi.render(scene, seed=seed), len(views))
        return image, time.perf_counter() - start

    def reference(spp: int, max_depth: int):
        first, _ = path_trace(spp, max_depth, seed=1)
        second, _ = path_trace(spp, max_depth, seed=2)
        noise_var_of_mean = np.mean((first - second) ** 2) / 4.0  # var(a - b) = 2 var; mean halves it
        return 0.5 * (first + second), noise_var_of_mean

    def net_rel_rmse(image, ref, ref_noise_var, image_noise_var=0.0):
        mse = np.mean((image - ref) ** 2) - ref_noise_var - image_noise_var
        return float(np.sqrt(max(mse, 0.0)) / np.sqrt(np.mean(ref**2)))

    start = time.perf_counter()
    prepared = prepare_density(density, args.density_scale, args.directions)
    ls_seconds = time.perf_counter() - start

    layer_images, layer_seconds = {}, {}
    for scheme in SCHEMES:
        scene = mi.load_dict(layer_scene(prepared, albedo, views, *size, steps=args.steps, scheme=scheme))
        split_views(mi.render(scene), len(views))  # compile
        start = time.perf_counter()
        layer_images[scheme] = split_views(mi.render(scene), len(views))
        layer_seconds[scheme] = time.perf_counter() - start

    # The layer shoots one ray through each pixel centre, the path tracer integrates over the pixel:
    # the same layer at 4x4 rays per pixel, box-filtered, separates that footprint error out.
    fine = mi.load_dict(layer_scene(prepared, albedo, views, 4 * size[0], 4 * size[1], steps=args.steps))
    supersampled = split_views(mi.render(fine), len(views))
    supersampled = supersampled.reshape(len(views), size[0], 4, size[1], 4, 3).mean(axis=(2, 4))

    single_ref, single_noise = reference(args.ref_spp, max_depth=2)
    errors = {scheme: net_rel_rmse(image, single_ref, single_noise) for scheme, image in layer_images.items()}
    layer_error = errors[DEFAULT_SCHEME]

    # The path tracer's own error at growing spp (its noise is what it has to beat).
    pt_spp, pt_seconds, pt_error, extrapolated = None, None, None, False
    spp = 1
    while spp <= args.ref_spp // 4:
        image, seconds = path_trace(spp, max_depth=2, seed=100 + spp)
        error = net_rel_rmse(image, single_ref, single_noise)
        if error <= layer_error:
            pt_spp, pt_seconds, pt_error = spp, seconds, error
            break
        spp *= 2
    if pt_spp is None and layer_error > 0:
        # Not reached within the budget: the error is noise, so it falls as 1/sqrt(spp) and the
        # time grows linearly; extrapolate from the last (largest) render.
        last_spp = spp // 2
        pt_spp = last_spp * (error / layer_error) ** 2
        pt_seconds = seconds * pt_spp / last_spp
        pt_error, extrapolated = layer_error, True

    multi_ref, multi_noise = reference(args.multi_spp, max_depth=-1)
    result = {
        "rel_rmse_single": layer_error,
        "rel_rmse_multi": net_rel_rmse(layer_images[DEFAULT_SCHEME], multi_ref, multi_noise),
        "pt_spp_equal_error": pt_spp,
        "pt_seconds_equal_error": pt_seconds,
        "layer_seconds": layer_seconds[DEFAULT_SCHEME],
        "default_scheme": DEFAULT_SCHEME,
        "rel_rmse_single_by_scheme": errors,
        "rel_rmse_single_4x4_rays_per_pixel": net_rel_rmse(supersampled, single_ref, single_noise),
        "layer_over_single_brightness": float(layer_images[DEFAULT_SCHEME].mean() / single_ref.mean()),
        "reference_noise_rel": float(np.sqrt(single_noise) / np.sqrt(np.mean(single_ref**2))),
        "multi_over_single_brightness": float(multi_ref.mean() / single_ref.mean()),
        "ls_seconds": ls_seconds,
        "pt_error_at_equal_spp": pt_error,
        "pt_equal_error_extrapolated": extrapolated,
        "setting": {
            "res": args.res, "image": args.image, "views": args.views, "steps": args.steps,
            "directions": args.directions, "density_scale": args.density_scale,
            "ref_spp": args.ref_spp, "multi_spp": args.multi_spp,
        },
        "machine": {"cpu_count": os.cpu_count(), "load_avg_1m": os.getloadavg()[0]},
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
