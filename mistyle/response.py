"""How a medium's render responds to its albedo: the path-traced measurements that the colour match
and the uniform baseline build on.

* ``albedo_renders``: ``volpath`` renders of one density with several albedos, in one scene;
* ``uniform_display_response``: ``f(a)``, the mean display value of the foreground at uniform grey
  albedo ``a`` (under a white light each channel renders independently, so ``f`` serves each);
* ``matched_uniform_albedo``: the one colour whose render shows a style's mean colour (the
  benchmark's must-beat baseline).
"""

from __future__ import annotations

import numpy as np

from .conventions import FOREGROUND_THRESHOLD


def albedo_renders(
    density: np.ndarray,
    density_scale: float,
    radiance: float,
    views,
    albedos,
    *,
    res: int,
    spp: int,
    max_depth: int = -1,
    batch: bool = False,
) -> list[np.ndarray]:
    """``volpath`` renders ``(V, res, res, 3)`` of ``density`` with each albedo of ``albedos`` (grids
    ``(Z, Y, X, 3)``, or grey levels for a uniform albedo), in one scene: only the albedo changes
    between renders. ``batch``: all views in one launch (faster, other noise than one sensor each).

    The scene's grids go back to the system when it returns: Dr.Jit keeps freed memory for its own
    next arrays, and a 512^3 grid's albedos are gigabytes that the network and the look, in torch and
    NumPy, would otherwise never get back."""
    import drjit as dr

    from .backend import active_variant
    from .scenes import LightSpec, albedo_parameter, pathtraced_scene, split_views

    mi = active_variant()
    shape = density.shape
    scene = mi.load_dict(
        pathtraced_scene(
            density,
            np.zeros(shape + (3,), np.float32),
            views,
            res=res,
            density_scale=density_scale,
            spp=spp,
            max_depth=max_depth,
            light=LightSpec("constant", radiance),
            seed=17,
            batch=batch,
        )
    )
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
            renders.append(
                np.stack([np.array(mi.render(scene, sensor=index), dtype=np.float32) for index in range(len(views))])
            )
    del scene, params
    dr.flush_malloc_cache()
    return renders


MATCH_LEVELS = tuple(np.geomspace(1e-4, 1.0, 17))


def uniform_display_response(
    density: np.ndarray,
    density_scale: float,
    radiance: float,
    views,
    levels,
    *,
    res: int,
    spp: int,
    pack_channels: bool = False,
) -> np.ndarray:
    """``f(a)`` at each of ``levels``: the mean display value of the path-traced foreground (the pixels
    that see the medium at the top level) of ``density`` with uniform grey albedo ``a``, made monotone
    against noise. Under a white light every channel renders independently, so ``f`` serves each.

    ``pack_channels``: render three levels at a time, one in each colour channel, for the same
    expectation from a third of the renders (the noise of the levels in one render is correlated)."""
    from .tone import display

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


def matched_uniform_albedo(
    density: np.ndarray,
    density_scale: float,
    radiance: float,
    style: np.ndarray,
    views,
    *,
    res: int = 64,
    spp: int = 16,
) -> np.ndarray:
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
