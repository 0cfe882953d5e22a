"""How close is the fast layer to Mitsuba's path tracer, and what would the path tracer need to match it?

One density and albedo (same box, scale, cameras and environment) are rendered with
  * the fast layer, every scheme (the default one is reported as "the layer");
  * the paper's layer ("plain": the Ls samples at the voxel centres interpolated as they are, rays
    marched through the whole medium box), which the default replaces: its error and both layers'
    forward + backward time (image and albedo gradient, median of 5 after a warm-up), in turns;
  * ``volpath`` with ``max_depth=2`` (single scattering, the layer's model), twice with different
    seeds so its own noise can be measured and taken out:
    ``rel_rmse = sqrt(max(0, MSE(layer, ref) - noise_var(ref))) / RMS(ref)``.
    The layer traces one ray through each pixel centre, so the reference traces its paths
    through the pixel centres too (volpath's ``sample()`` on the layer's own camera rays): the
    error is the layer's, not the difference between a point sample and a pixel average. The
    same numbers against ordinary pixel-averaging renders are reported as ``..._pixel_area``;
  * ``volpath`` at 1, 2, 4, ... spp until its own (net) error reaches the layer's (extrapolated as
    1/sqrt(spp) past the budget);
  * ``volpath`` with ``max_depth=-1`` (multiple scattering, the final render's model).

Prints one JSON line with ``rel_rmse_single``, ``rel_rmse_multi``, ``pt_spp_equal_error``,
``pt_seconds_equal_error``, ``layer_seconds``, ``rel_rmse_single_plain``, ``forward_backward_seconds``
(default and plain) and details.

    python experiments/layer_vs_pathtraced.py            # 64^3, N=64, K=128, 2 views at 128^2
    python experiments/layer_vs_pathtraced.py --quick    # 24^3, 32^2, well under a minute
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from mistyle.conventions import DEFAULT_DENSITY_SCALE


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--res", type=int, default=64)
    parser.add_argument("--image", type=int, default=128)
    parser.add_argument("--views", type=int, default=2)
    parser.add_argument("--steps", type=int, default=64)
    parser.add_argument("--directions", type=int, default=128)
    parser.add_argument(
        "--ls-grid-factor",
        type=int,
        default=1,
        help="Ls on a grid this many times finer (3: 0.35%% at 80 steps, 27x the Ls memory)",
    )
    parser.add_argument("--density-scale", type=float, default=DEFAULT_DENSITY_SCALE)
    parser.add_argument("--ref-spp", type=int, default=4096, help="spp of each single-scattering reference")
    parser.add_argument("--multi-spp", type=int, default=1024, help="spp of each multiple-scattering reference")
    args = parser.parse_args()
    if args.quick:
        args.res, args.image, args.ref_spp, args.multi_spp, args.directions = 24, 32, 1024, 256, 64

    from mistyle.backend import use_variant
    from mistyle.conventions import DEFAULT_LAYER_SCHEME as DEFAULT_SCHEME
    from mistyle.conventions import LAYER_SCHEMES as SCHEMES
    from mistyle.integrators import PreparedDensity, layer_scene, prepare_density
    from mistyle.integrators.inscatter import inscattered_radiance
    from mistyle.pathtrace import (
        net_rel_rmse,
        pixel_centre_estimate,
        two_seed_reference,
    )
    from mistyle.scenes import pathtraced_scene, split_views

    mi = use_variant("cpu")

    density, albedo, views = scene_inputs(args.res, args.views)
    size = (args.image, args.image)
    scenes = {
        depth: mi.load_dict(
            pathtraced_scene(
                density, albedo, views, res=size, density_scale=args.density_scale, max_depth=depth, batch=True
            )
        )
        for depth in (2, -1)
    }

    def path_trace_pixel_area(spp: int, max_depth: int, seed: int):
        start = time.perf_counter()
        image = mi.render(scenes[max_depth], spp=spp, seed=seed)
        return split_views(image, len(views)), time.perf_counter() - start

    def path_trace_pixel_centres(spp: int, max_depth: int, seed: int):
        start = time.perf_counter()
        image = pixel_centre_estimate(scenes[max_depth], spp, seed, len(views))
        return image, time.perf_counter() - start

    def reference(render, spp: int, max_depth: int):
        return two_seed_reference(lambda count, seed: render(count, max_depth, seed)[0], spp)

    start = time.perf_counter()
    prepared = prepare_density(density, args.density_scale, args.directions, ls_grid_factor=args.ls_grid_factor)
    ls_seconds = time.perf_counter() - start
    # The paper's layer: the Ls samples themselves in the texture, rays marched through the whole box.
    samples = inscattered_radiance(prepared.sigma_t, args.directions)
    plain_scene = layer_scene(
        PreparedDensity(density, args.density_scale, samples, args.directions),
        albedo,
        views,
        res=size,
        steps=args.steps,
    )
    plain_scene["integrator"]["march_min"] = plain_scene["integrator"]["bbox_min"]
    plain_scene["integrator"]["march_max"] = plain_scene["integrator"]["bbox_max"]
    plain_scene = mi.load_dict(plain_scene)
    default_scene = mi.load_dict(layer_scene(prepared, albedo, views, res=size, steps=args.steps))
    forward_backward = {"default": [], "plain": []}
    for repeat in range(6):  # in turns, so both see the same load; the first round compiles
        for name, scene in (("default", default_scene), ("plain", plain_scene)):
            seconds = forward_backward_seconds(mi, scene)
            if repeat:
                forward_backward[name].append(seconds)
    forward_backward = {name: float(np.median(times)) for name, times in forward_backward.items()}
    plain_layer = split_views(mi.render(plain_scene), len(views))

    layer_images, layer_seconds = {}, {}
    for scheme in SCHEMES:
        scene = mi.load_dict(layer_scene(prepared, albedo, views, res=size, steps=args.steps, scheme=scheme))
        split_views(mi.render(scene), len(views))  # compile
        start = time.perf_counter()
        layer_images[scheme] = split_views(mi.render(scene), len(views))
        layer_seconds[scheme] = time.perf_counter() - start
    layer = layer_images[DEFAULT_SCHEME]

    single_ref, single_noise = reference(path_trace_pixel_centres, args.ref_spp, max_depth=2)
    errors = {scheme: net_rel_rmse(image, single_ref, single_noise) for scheme, image in layer_images.items()}
    layer_error = errors[DEFAULT_SCHEME]
    plain_error = net_rel_rmse(plain_layer, single_ref, single_noise)

    # The path tracer's own error at growing spp: its noise is what it has to beat.
    pt_spp, pt_seconds, extrapolated = None, None, False
    spp = 1
    while spp <= args.ref_spp // 4:
        image, seconds = path_trace_pixel_centres(spp, max_depth=2, seed=100 + spp)
        error = net_rel_rmse(image, single_ref, single_noise)
        if error <= layer_error:
            pt_spp, pt_seconds = spp, seconds
            break
        spp *= 2
    if pt_spp is None and layer_error > 0:
        # Past the budget the error is noise: it falls as 1/sqrt(spp) while time grows linearly.
        last_spp = spp // 2
        pt_spp = last_spp * (error / layer_error) ** 2
        pt_seconds = seconds * pt_spp / last_spp
        extrapolated = True

    multi_ref, multi_noise = reference(path_trace_pixel_centres, args.multi_spp, max_depth=-1)
    area_single, area_single_noise = reference(path_trace_pixel_area, args.ref_spp, max_depth=2)
    area_multi, area_multi_noise = reference(path_trace_pixel_area, args.multi_spp, max_depth=-1)

    result = {
        "rel_rmse_single": layer_error,
        "rel_rmse_multi": net_rel_rmse(layer, multi_ref, multi_noise),
        "pt_spp_equal_error": pt_spp,
        "pt_seconds_equal_error": pt_seconds,
        "layer_seconds": layer_seconds[DEFAULT_SCHEME],
        "rel_rmse_single_plain": plain_error,
        "plain_over_single_brightness": float(plain_layer.mean() / single_ref.mean()),
        "forward_backward_seconds": forward_backward,
        "forward_backward_ratio": forward_backward["default"] / forward_backward["plain"],
        "pt_equal_error_extrapolated": extrapolated,
        "default_scheme": DEFAULT_SCHEME,
        "rel_rmse_single_by_scheme": errors,
        "layer_over_single_brightness": float(layer.mean() / single_ref.mean()),
        "multi_over_single_brightness": float(multi_ref.mean() / single_ref.mean()),
        "reference_noise_rel": float(np.sqrt(single_noise / np.mean(single_ref**2))),
        "rel_rmse_single_pixel_area": net_rel_rmse(layer, area_single, area_single_noise),
        "rel_rmse_multi_pixel_area": net_rel_rmse(layer, area_multi, area_multi_noise),
        "ls_seconds": ls_seconds,
        "setting": {
            "res": args.res,
            "image": args.image,
            "views": args.views,
            "steps": args.steps,
            "directions": args.directions,
            "density_scale": args.density_scale,
            "ls_grid_factor": args.ls_grid_factor,
            "ref_spp": args.ref_spp,
            "multi_spp": args.multi_spp,
        },
        "machine": {"cpu_count": os.cpu_count(), "load_avg_1m": os.getloadavg()[0]},
    }
    print(json.dumps(result))


def scene_inputs(res: int, view_count: int):
    """The experiment's scene: ``(density (res^3), albedo (res^3, 3), views)``, a pyroclastic sphere with
    a colour-noise albedo seen from ``view_count`` views around the orbit (also ``ablations.py``'s
    claim-8 contact sheet)."""
    from mistyle.data.procedural import colour_noise_albedo, pyroclastic_sphere
    from mistyle.scenes import CameraPath

    density = pyroclastic_sphere((res,) * 3, seed=7)
    return density, colour_noise_albedo(density.shape, seed=11), CameraPath().turntable(view_count, offset=0.125)


def forward_backward_seconds(mi, scene) -> float:
    """One forward render with the albedo differentiable and its backward pass to the albedo."""
    import drjit as dr

    params = mi.traverse(scene)
    start = time.perf_counter()
    dr.enable_grad(params["integrator.albedo"])
    params.update()
    image = mi.render(scene, params, seed=0, spp=1)
    dr.backward(dr.mean(image, axis=None))
    dr.eval(dr.grad(params["integrator.albedo"]))
    seconds = time.perf_counter() - start
    dr.disable_grad(params["integrator.albedo"])
    return seconds


if __name__ == "__main__":
    main()
