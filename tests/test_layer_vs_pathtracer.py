"""The fast layer and Mitsuba's volpath agree on the same scene (single scattering)."""

import numpy as np
import pytest

from mistyle.data.procedural import colour_noise_albedo
from mistyle.integrators import layer_scene, prepare_density
from mistyle.pathtrace import net_rel_rmse, two_seed_reference
from mistyle.scenes import CameraPath, pathtraced_scene, split_views


def test_net_rel_rmse_takes_the_references_noise_out():
    rng = np.random.default_rng(0)
    truth = rng.random((2, 8, 8, 3)) + 0.5
    image = truth * 1.02  # 2% too bright everywhere
    renders = {seed: truth + rng.normal(0.0, 0.05, truth.shape) for seed in (1, 2)}
    reference, noise_var = two_seed_reference(lambda spp, seed: renders[seed], spp=1)
    assert noise_var == pytest.approx(0.05**2 / 2, rel=0.15)  # the mean of two halves the variance
    expected = 0.02 * np.sqrt(np.mean(truth**2) / np.mean(reference**2))
    assert net_rel_rmse(image, reference, noise_var) == pytest.approx(expected, rel=0.15)
    plain = np.sqrt(np.mean((image - reference) ** 2) / np.mean(reference**2))
    assert plain > 1.5 * net_rel_rmse(image, reference, noise_var)  # the noise would dominate otherwise
    assert net_rel_rmse(reference, reference, noise_var) == 0.0


def test_layer_agrees_with_single_scattering_path_tracer(mi):
    density = np.full((16, 16, 16), 0.5, np.float32)
    density[:2] = density[-2:] = 0.0  # some structure: empty top and bottom slabs
    albedo = colour_noise_albedo(density.shape, seed=2)
    views = CameraPath().turntable(2, offset=0.1)
    prepared = prepare_density(density, 6.0, directions=128)
    layer = split_views(mi.render(mi.load_dict(layer_scene(prepared, albedo, views, res=48))), 2)
    layer = layer.reshape(2, 12, 4, 12, 4, 3).mean(axis=(2, 4))  # the path tracer integrates over pixels

    def path_traced(spp, seed):
        scene = mi.load_dict(
            pathtraced_scene(
                density, albedo, views, res=12, density_scale=6.0, spp=spp, max_depth=2, seed=seed, batch=True
            )
        )
        return split_views(mi.render(scene, seed=seed), 2)

    reference, noise_var = two_seed_reference(path_traced, spp=512)
    rel_rmse = net_rel_rmse(layer, reference, noise_var)
    print(f"layer/PT brightness {layer.mean() / reference.mean():.4f}, net rel RMSE {rel_rmse:.4f}")
    assert abs(layer.mean() / reference.mean() - 1) < 0.02
    assert rel_rmse < 0.03

    # Multiple scattering makes the medium clearly brighter: the layer is a single-scatter model.
    multi = mi.load_dict(pathtraced_scene(density, albedo, views, res=12, density_scale=6.0, spp=64, batch=True))
    assert split_views(mi.render(multi), 2).mean() > 1.1 * reference.mean()
