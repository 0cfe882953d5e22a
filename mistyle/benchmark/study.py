"""What studies built on the benchmark share: its metric renders' options and scoring, in one spelling.

A study (``experiments/``) scores its arms exactly as ``mistyle-bench`` scores methods:
``runner.score`` from ``runner.metric_views``, next to ``uniform_baseline``.
"""

from __future__ import annotations

import numpy as np

from .runner import METRIC_VIEWS, metric_views, score

__all__ = ["METRIC_VIEWS", "add_metric_arguments", "metric_views", "score", "uniform_baseline"]


def add_metric_arguments(parser, res: int = 128, spp: int = 16) -> None:
    """``--res`` and ``--spp`` of the metric renders and ``--cache`` of the held-out densities."""
    parser.add_argument("--res", type=int, default=res, help="metric renders' side")
    parser.add_argument("--spp", type=int, default=spp, help="metric renders' paths per pixel")
    parser.add_argument("--cache", default="data/heldout", help="where held-out densities are cached")


def uniform_baseline(density, style, views, *, density_scale: float, radiance: float) -> np.ndarray:
    """The must-beat baseline's albedo ``(Z, Y, X, 3)``: one colour matched to the style's mean
    (``methods.uniform_albedo``'s, for a density scale and light given directly)."""
    from ..response import matched_uniform_albedo

    colour = matched_uniform_albedo(density, density_scale, radiance, style, views[:2], res=64, spp=16)
    return np.ascontiguousarray(np.broadcast_to(colour, density.shape + (3,)), dtype=np.float32)
