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
from .stops import raise_if_requested

MAX_PASS_SAMPLES = 1 << 26
"""Paths per launch of the path tracer (a 256^2 image at 1024 spp); larger renders go in passes."""


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
    max_pass_samples: int | None = None,
) -> tuple[list[np.ndarray], list[float]]:
    """``render`` for several ``View``s of one scene: ``([(res, res, 3)] images, [seconds per view])``.

    ``progress(done, count, seconds)`` is called after each view when given. ``bricks``: voxels per
    brick of the medium's majorant bricks (``scenes.bricks``; the same image in expectation, faster
    on sparse volumes), ``0`` for one medium; by default ``DEFAULT_BRICK``, and 0 under a coat. Large
    ``res^2 spp`` render in several passes (``sample_passes``; ``max_pass_samples``: their limit).
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
    passes = sample_passes(res, spp, MAX_PASS_SAMPLES if max_pass_samples is None else max_pass_samples)
    images, seconds = [], []
    for index in range(len(views)):
        raise_if_requested()
        started = time.perf_counter()
        if len(passes) == 1:
            image = np.array(mi.render(scene, sensor=index), dtype=np.float32)
        else:  # the mean of passes weighted by their samples: the same estimator as one pass of ``spp``
            total = np.zeros((res, res, 3), np.float64)
            for number, count in enumerate(passes):
                rendered = mi.render(scene, sensor=index, spp=count, seed=seed * len(passes) + number + 1)
                total += np.array(rendered, dtype=np.float64) * count
            image = (total / spp).astype(np.float32)
        images.append(image)
        seconds.append(time.perf_counter() - started)
        if progress is not None:
            progress(index + 1, len(views), seconds[-1])
    return images, seconds


def sample_passes(res: int, spp: int, max_pass_samples: int = MAX_PASS_SAMPLES) -> list[int]:
    """Samples per pixel of each pass of a ``res``^2 image at ``spp``: one pass when ``res^2 spp`` fits
    ``max_pass_samples``, else as few near-equal passes as fit (their sum is ``spp``).

    One launch of ``res^2 spp`` paths beyond about 2^31 makes Mitsuba split it into passes whose count
    must divide ``spp`` (an error otherwise) and can run out of memory; passes of our own avoid both."""
    pixels = res * res
    per_pass = max(1, max_pass_samples // pixels)
    if spp <= per_pass:
        return [spp]
    count = -(-spp // per_pass)
    return [spp // count + (1 if number < spp % count else 0) for number in range(count)]
