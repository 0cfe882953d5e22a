"""Multiple-scattering calibration: the network is trained under single scattering.

The path tracer adds multiple scattering, which brightens and desaturates a medium relative to
the fast layer the network was trained through. ``calibrate_albedo`` undoes this to first order,
per density: render the density with uniform albedo ``a`` at a few levels with ``volpath``
(multiple scattering) to measure the mean foreground radiance ``g(a)``; the fast layer's is
``a * h`` (linear in albedo). Each albedo value ``a`` is then replaced, per channel, by
``g^{-1}(a * h)``: the albedo whose multiply-scattered brightness equals the single-scattered
brightness the network aimed for. ``g`` is monotone, so the inverse is a table lookup.

(The other correction, refining the albedo with the path tracer in the loop, is ``mistyle.fit``.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .conventions import FOREGROUND_THRESHOLD

LEVELS = (0.1, 0.25, 0.4, 0.55, 0.7, 0.85, 1.0)


@dataclass
class ScatteringCalibration:
    levels: np.ndarray  # albedo levels a, increasing, starting with 0
    multiple: np.ndarray  # g(a): mean path-traced foreground radiance at uniform albedo a
    single: float  # h: mean fast-layer foreground radiance at uniform albedo 1
    seconds: float

    def apply(self, albedo: np.ndarray) -> np.ndarray:
        """``(..., 3)`` albedo -> calibrated albedo (same shape), ``g^{-1}(a h)`` per value."""
        target = np.asarray(albedo, dtype=np.float64) * self.single
        return np.clip(np.interp(target, self.multiple, self.levels), 0.0, 1.0).astype(np.float32)

    def as_dict(self) -> dict:
        return {"levels": self.levels.tolist(), "multiple": self.multiple.tolist(), "single": self.single,
                "seconds": self.seconds}


def measure_calibration(density: np.ndarray, density_scale: float, radiance: float, views, res: int = 64,
                        spp: int = 32, levels=LEVELS, prepared=None) -> ScatteringCalibration:
    """Measure ``g(a)`` and ``h`` for ``density`` under the constant environment ``radiance`` from ``views``.

    ``prepared``: the density's ``PreparedDensity`` when the caller has computed its Ls already.
    """
    import time

    import torch

    from .backend import active_variant
    from .bridge_torch import render_views
    from .integrators import prepare_density

    active_variant()
    started = time.perf_counter()
    shape = density.shape
    if prepared is None:
        prepared = prepare_density(density, density_scale)
    with torch.no_grad():
        layer = render_views(torch.ones((3,) + shape), prepared, views, res, radiance=radiance).numpy()
    mask = layer.max(axis=1) > FOREGROUND_THRESHOLD  # (V, H, W)
    if not mask.any():
        raise ValueError("The medium is not visible from the calibration views.")
    single = float(layer.transpose(0, 2, 3, 1)[mask].mean())
    multiple = [0.0] + [float(images[mask].mean()) for images in albedo_renders(
        density, density_scale, radiance, views, levels, res=res, spp=spp)]
    multiple = np.maximum.accumulate(np.array(multiple))  # monotone despite noise
    return ScatteringCalibration(np.array((0.0,) + tuple(levels)), multiple, single, time.perf_counter() - started)


def albedo_renders(density: np.ndarray, density_scale: float, radiance: float, views, albedos, *, res: int,
                   spp: int, max_depth: int = -1, batch: bool = False) -> list[np.ndarray]:
    """``volpath`` renders ``(V, res, res, 3)`` of ``density`` with each albedo of ``albedos`` (grids
    ``(Z, Y, X, 3)``, or grey levels for a uniform albedo), in one scene: only the albedo changes
    between renders. ``batch``: all views in one launch (faster, other noise than one sensor each)."""
    from .backend import active_variant
    from .scenes import LightSpec, albedo_parameter, pathtraced_scene, split_views

    mi = active_variant()
    shape = density.shape
    scene = mi.load_dict(pathtraced_scene(density, np.zeros(shape + (3,), np.float32), views, res=res,
                                          density_scale=density_scale, spp=spp, max_depth=max_depth,
                                          light=LightSpec("constant", radiance), seed=17, batch=batch))
    params = mi.traverse(scene)
    albedo_key = albedo_parameter(params)
    renders = []
    for albedo in albedos:
        grid = np.broadcast_to(np.asarray(albedo, np.float32), shape + (3,))
        params[albedo_key] = mi.TensorXf(np.ascontiguousarray(grid))
        params.update()
        if batch:
            renders.append(split_views(mi.render(scene), len(views)))
        else:
            renders.append(np.stack([np.array(mi.render(scene, sensor=index), dtype=np.float32)
                                     for index in range(len(views))]))
    return renders


MATCH_LEVELS = tuple(np.geomspace(1e-4, 1.0, 17))


def uniform_display_response(density: np.ndarray, density_scale: float, radiance: float, views, levels, *,
                             res: int, spp: int, pack_channels: bool = False) -> np.ndarray:
    """``f(a)`` at each of ``levels``: the mean display value of the path-traced foreground (the pixels
    that see the medium at the top level) of ``density`` with uniform grey albedo ``a``, made monotone
    against noise. Under a white light every channel renders independently, so ``f`` serves each.

    ``pack_channels``: render three levels at a time, one in each colour channel, for the same
    expectation from a third of the renders (the noise of the levels in one render is correlated)."""
    from .display import display

    levels = np.asarray(levels, dtype=np.float64)
    if pack_channels:
        count = -(-len(levels) // 3)  # renders; render r holds levels r, r + count, r + 2 count
        packed = np.concatenate([levels, np.full(3 * count - len(levels), levels[-1])]).reshape(3, count).T
        renders = albedo_renders(density, density_scale, radiance, views, packed, res=res, spp=spp)
        per_level = [renders[i % count][..., i // count] for i in range(len(levels))]  # (V, H, W) each
    else:
        per_level = albedo_renders(density, density_scale, radiance, views, levels, res=res, spp=spp)
    top = per_level[-1]
    mask = (top if pack_channels else top.max(axis=-1)) > FOREGROUND_THRESHOLD
    if not mask.any():
        raise ValueError("The medium is not visible from the matching views.")
    return np.maximum.accumulate([float(display(images[mask]).mean()) for images in per_level])


def matched_uniform_albedo(density: np.ndarray, density_scale: float, radiance: float, style: np.ndarray, views, *,
                           res: int = 64, spp: int = 16) -> np.ndarray:
    """The uniform RGB albedo ``(3,)`` whose path-traced foreground has the style's mean display colour.

    The must-beat baseline of the fidelity benchmark: the best a medium of one colour can do. Under a
    white constant light the channels render independently, so one sweep of grey levels
    ``MATCH_LEVELS`` gives the mean display value ``f(a)`` of every channel (over the pixels that see
    the medium at full albedo); each channel is ``f^{-1}`` of the style's mean in that channel
    (``f`` is monotone; interpolated in log albedo).
    """
    means = uniform_display_response(density, density_scale, radiance, views, MATCH_LEVELS, res=res, spp=spp)
    target = np.asarray(style, dtype=np.float64).reshape(-1, 3).mean(axis=0)
    log_albedo = np.interp(target, means, np.log(MATCH_LEVELS))
    return np.exp(log_albedo).astype(np.float32)
