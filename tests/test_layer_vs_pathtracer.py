"""The fast layer and Mitsuba's volpath agree on the same scene (single scattering)."""

import numpy as np

from mistyle.data.procedural import colour_noise_albedo
from mistyle.scenes import (
    CameraPath,
    layer_scene,
    pathtraced_scene,
    prepare_density,
    split_views,
)


def test_layer_agrees_with_single_scattering_path_tracer(mi):
    density = np.full((16, 16, 16), 0.5, np.float32)
    density[:2] = density[-2:] = 0.0  # some structure: empty top and bottom slabs
    albedo = colour_noise_albedo(density.shape, seed=2)
    views = CameraPath().turntable(2, offset=0.1)
    size = (12, 12)
    prepared = prepare_density(density, 6.0, directions=128)
    layer = split_views(mi.render(mi.load_dict(layer_scene(prepared, albedo, views, 48, 48))), 2)
    layer = layer.reshape(2, 12, 4, 12, 4, 3).mean(axis=(2, 4))  # the path tracer integrates over pixels

    def path_traced(seed):
        scene = mi.load_dict(pathtraced_scene(density, 6.0, albedo, views, *size, spp=512, max_depth=2, seed=seed))
        return split_views(mi.render(scene, seed=seed), 2)

    first, second = path_traced(1), path_traced(2)
    reference = 0.5 * (first + second)
    noise_var = np.mean((first - second) ** 2) / 4
    rel_rmse = np.sqrt(max(np.mean((layer - reference) ** 2) - noise_var, 0.0) / np.mean(reference**2))
    print(f"layer/PT brightness {layer.mean() / reference.mean():.4f}, net rel RMSE {rel_rmse:.4f}")
    assert abs(layer.mean() / reference.mean() - 1) < 0.02
    assert rel_rmse < 0.03

    # Multiple scattering makes the medium clearly brighter: the layer is a single-scatter model.
    multi = mi.load_dict(pathtraced_scene(density, 6.0, albedo, views, *size, spp=64, max_depth=-1))
    assert split_views(mi.render(multi), 2).mean() > 1.1 * reference.mean()
