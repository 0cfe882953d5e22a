"""Shared pieces of the style-fidelity benchmark and the objective study (imported by both scripts).

Every volume is scored the same way: path traced (``volpath``, multiple scattering, the training
light) from ``METRIC_VIEWS`` views around the orbit at ``--res`` with ``--spp`` paths per pixel, then
``mistyle.objective.metrics.style_fidelity`` against the style.
"""

from __future__ import annotations

import numpy as np

METRIC_VIEWS = 3


def add_metric_arguments(parser, res: int = 128, spp: int = 16) -> None:
    """``--res`` and ``--spp`` of the metric renders and ``--cache`` of the held-out densities: one
    spelling for every script that scores with ``score``."""
    parser.add_argument("--res", type=int, default=res, help="metric renders' side")
    parser.add_argument("--spp", type=int, default=spp, help="metric renders' paths per pixel")
    parser.add_argument("--cache", default="data/heldout", help="where held-out densities are cached")


def metric_views(camera_distance: float, count: int = METRIC_VIEWS):
    """``count`` views evenly around the orbit, starting at the held-out view ``--view`` defaults to."""
    from mistyle.conventions import HELD_OUT_VIEW
    from mistyle.scenes import CameraPath

    return CameraPath(distance=camera_distance).turntable(count, offset=HELD_OUT_VIEW)


def score(density, albedo, style, views, *, res: int, spp: int, density_scale: float, radiance: float) -> dict:
    """Fidelity metrics of ``albedo (Z, Y, X, 3)`` on ``density``, path traced from ``views``."""
    from mistyle.api import path_trace
    from mistyle.objective.metrics import style_fidelity

    images, _ = path_trace(density, albedo, views, res=res, spp=spp, density_scale=density_scale,
                           light=f"constant:{radiance}")
    return style_fidelity(images, style), images


def uniform_baseline(density, style, views, *, density_scale: float, radiance: float) -> np.ndarray:
    """The must-beat baseline's albedo grid ``(Z, Y, X, 3)``: one colour, matched to the style's mean."""
    from mistyle.correct import matched_uniform_albedo

    colour = matched_uniform_albedo(density, density_scale, radiance, style, views[:2], res=64, spp=16)
    return np.broadcast_to(colour, density.shape + (3,)).copy()
