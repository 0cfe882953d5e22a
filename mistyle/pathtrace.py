"""Running the path tracer: images of a medium (``path_trace``) and estimates along the layer's rays.

``path_trace`` renders a density and an albedo grid with Mitsuba's ``volpath`` from several views
of one scene (``scenes.pathtraced_scene`` builds it); everything that shows a final image calls it
(``mistyle.render``, the pipeline, the benchmark). The differentiable path-traced views used in a
fit are ``bridge_torch.PathTracedViews``, since torch meets Dr.Jit only there.

The layer shoots one ray through each pixel centre; Mitsuba's ``mi.render`` averages paths over
each pixel's area. To measure the layer's model error without the point-versus-area difference,
``pixel_centre_estimate`` runs the scene's integrator (e.g. ``volpath``) on the same pixel-centre
rays that the layer uses, many paths per ray.
"""

from __future__ import annotations

import time

import numpy as np

from .backend import active_variant
from .conventions import DEFAULT_DENSITY_SCALE
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


def path_trace(
    density,
    albedo,
    views,
    *,
    res: int = 256,
    spp: int = 64,
    max_depth: int = -1,
    density_scale: float = DEFAULT_DENSITY_SCALE,
    light="constant",
    coat_ior: float | None = None,
    coat_mesh=None,
    device: str = "cpu",
    seed: int = 0,
    progress=None,
    bricks: int | None = None,
) -> tuple[list[np.ndarray], list[float]]:
    """``render`` for several ``View``s of one scene: ``([(res, res, 3)] images, [seconds per view])``.

    ``progress(done, count, seconds)`` is called after each view when given. ``bricks``: voxels per
    brick of the medium's majorant bricks (``scenes.bricks``; the same image in expectation, faster
    on sparse volumes), ``0`` for one medium; by default ``DEFAULT_BRICK``, and 0 under a coat.
    """
    from .backend import use_variant
    from .scenes import LightSpec, pathtraced_scene
    from .scenes.bricks import DEFAULT_BRICK
    from .volume import validate_albedo, validate_density

    mi = use_variant(device)
    grid = validate_density(density)
    colours = validate_albedo(albedo, grid.shape)
    if not 1 <= res <= 8192 or spp < 1:
        raise ValueError(f"Need 1 <= res <= 8192 and spp >= 1, got res={res}, spp={spp}.")
    light = light if isinstance(light, LightSpec) else LightSpec.parse(light)
    if bricks is None:
        bricks = 0 if coat_ior is not None else DEFAULT_BRICK
    scene = mi.load_dict(
        pathtraced_scene(
            grid,
            colours,
            views,
            res=res,
            density_scale=density_scale,
            spp=spp,
            max_depth=max_depth,
            light=light,
            coat_ior=coat_ior,
            coat_mesh=coat_mesh,
            seed=seed,
            bricks=bricks,
        )
    )
    images, seconds = [], []
    for index in range(len(views)):
        started = time.perf_counter()
        images.append(np.array(mi.render(scene, sensor=index), dtype=np.float32))
        seconds.append(time.perf_counter() - started)
        if progress is not None:
            progress(index + 1, len(views), seconds[-1])
    return images, seconds
