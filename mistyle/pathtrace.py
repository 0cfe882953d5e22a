"""Path-traced estimates along the fast layer's own camera rays.

The layer shoots one ray through each pixel centre; Mitsuba's ``mi.render`` averages paths over
each pixel's area. To measure the layer's model error without the point-versus-area difference,
``pixel_centre_estimate`` runs the scene's integrator (e.g. ``volpath``) on the same pixel-centre
rays that the layer uses, many paths per ray.
"""

from __future__ import annotations

import numpy as np

from .backend import active_variant
from .scenes.cameras import split_views


def pixel_centre_estimate(scene, spp: int, seed: int, view_count: int, chunk: int = 256) -> np.ndarray:
    """Mean radiance of ``spp`` paths along each pixel-centre ray: ``(V, H, W, 3)`` float32.

    ``scene`` holds a batch sensor of ``view_count`` views (``mistyle.scenes.pathtraced_scene(..., batch=True)``).
    """
    from .integrators import register

    mi = active_variant()
    register()
    from .integrators.single_scatter import pixel_centre_rays

    sensor = scene.sensors()[0]
    width, height = (int(v) for v in sensor.film().crop_size())
    pixels = width * height
    total = np.zeros((pixels, 3))
    for first in range(0, spp, chunk):
        count = min(chunk, spp - first)
        ray, weight, _ = pixel_centre_rays(sensor, count)
        sampler = mi.load_dict({"type": "independent"})
        sampler.seed(seed * 1_000_003 + first, pixels * count)
        radiance, _, _ = scene.integrator().sample(scene, sampler, ray, None, True)
        radiance = radiance * weight
        channels = np.stack([np.asarray(radiance[c]) for c in range(3)], axis=-1)
        total += channels.reshape(pixels, count, 3).sum(axis=1)
    return split_views((total / spp).astype(np.float32).reshape(height, width, 3), view_count)


def two_seed_reference(render, spp: int):
    """Mean of two independent renders and the noise variance of that mean (per value)."""
    first, second = render(spp, 1), render(spp, 2)
    return 0.5 * (first + second), float(np.mean((first - second) ** 2) / 4.0)


def net_rel_rmse(image: np.ndarray, reference: np.ndarray, reference_noise_var: float) -> float:
    """Relative RMSE of ``image`` against a noisy reference, with the reference's noise taken out.

    ``sqrt(max(0, MSE(image, reference) - noise_var)) / RMS(reference)``, where ``noise_var`` is the
    per-value noise variance of the reference (``two_seed_reference`` estimates it).
    """
    mse = float(np.mean((image - reference) ** 2)) - reference_noise_var
    return float(np.sqrt(max(mse, 0.0)) / np.sqrt(np.mean(reference**2)))
