"""Style-match metrics for experiments and training logs.

Images are numpy or torch ``(H, W, 3)``. Renders are linear radiance and go through the training
tone curve (``mistyle.display``) so they are compared with style images in display space.
"""

from __future__ import annotations

import numpy as np
import torch

from ..conventions import FOREGROUND_THRESHOLD
from ..display import display
from ..warp import semi_lagrangian_warp


def foreground_pixels(render: np.ndarray, threshold: float = FOREGROUND_THRESHOLD) -> np.ndarray:
    """Tone-mapped RGB of the pixels that see the medium (any channel above ``threshold``): ``(N, 3)``."""
    render = np.asarray(render, dtype=np.float32)
    keep = render.max(axis=-1) > threshold
    return display(render[keep]).reshape(-1, 3)


MAX_METRIC_POINTS = 1 << 18
"""Point sets larger than this are subsampled (without replacement, seeded) before the sliced
Wasserstein distance, so its cost is bounded whatever the image size: 2^18 points x 128 projections
in float64 is 256 MB. Measured on a 1000x1000 photograph against a 64^2 render, the subsampled
distance differs from the exact one by under 0.5% (``tests/test_losses.py``)."""


def sliced_wasserstein(a: np.ndarray, b: np.ndarray, projections: int = 128, seed: int = 0) -> float:
    """Sliced 2-Wasserstein distance between two RGB point sets ``(N, 3)`` and ``(M, 3)``.

    ``sqrt(mean over random unit directions of W2^2 between the 1D projections)``; quantiles are
    compared at a common count, so the sets need not have equal sizes. Sets of more than
    ``MAX_METRIC_POINTS`` points are subsampled first.
    """
    rng = np.random.default_rng(seed)
    a, b = (np.asarray(bounded_points(points, rng), dtype=np.float64) for points in (a, b))
    if len(a) == 0 or len(b) == 0:
        raise ValueError("sliced_wasserstein needs non-empty point sets (did the render see any medium?).")
    directions = np.random.default_rng(seed).normal(size=(projections, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    count = max(len(a), len(b))
    levels = (np.arange(count) + 0.5) / count
    qa = _sorted_quantiles(np.sort(a @ directions.T, axis=0), levels)
    qb = _sorted_quantiles(np.sort(b @ directions.T, axis=0), levels)
    return float(np.sqrt(np.mean((qa - qb) ** 2)))


def bounded_points(points, rng: np.random.Generator) -> np.ndarray:
    """``points`` as ``(N, 3)``, subsampled to ``MAX_METRIC_POINTS`` rows when larger (no copy otherwise)."""
    points = np.asarray(points).reshape(-1, 3)
    if len(points) <= MAX_METRIC_POINTS:
        return points
    return points[np.sort(rng.choice(len(points), MAX_METRIC_POINTS, replace=False))]


def _sorted_quantiles(sorted_values: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Quantiles at ``levels`` in (0, 1) of each column of column-sorted ``(N, P)`` values (linear)."""
    position = np.clip(levels * len(sorted_values) - 0.5, 0, len(sorted_values) - 1)
    low = np.floor(position).astype(np.int64)
    high = np.minimum(low + 1, len(sorted_values) - 1)
    weight = (position - low)[:, None]
    return sorted_values[low] * (1 - weight) + sorted_values[high] * weight


def colour_histogram_distance(a: np.ndarray, b: np.ndarray, bins: int = 8) -> float:
    """Total-variation distance between normalised ``bins^3`` RGB histograms of two point sets, in [0, 1]."""
    edges = np.linspace(0.0, 1.0, bins + 1)
    ha, _ = np.histogramdd(np.clip(np.asarray(a).reshape(-1, 3), 0, 1), bins=(edges,) * 3)
    hb, _ = np.histogramdd(np.clip(np.asarray(b).reshape(-1, 3), 0, 1), bins=(edges,) * 3)
    return float(0.5 * np.abs(ha / max(ha.sum(), 1) - hb / max(hb.sum(), 1)).sum())


def style_distance(render: np.ndarray, style: np.ndarray) -> dict:
    """Sliced Wasserstein and colour-histogram distances between a render's foreground and a style."""
    rng = np.random.default_rng(0)
    pixels = bounded_points(foreground_pixels(render), rng)
    style_pixels = bounded_points(np.asarray(style, dtype=np.float32), rng)
    return {"swd": sliced_wasserstein(pixels, style_pixels), "hist": colour_histogram_distance(pixels, style_pixels)}


def temporal_flicker(volumes: np.ndarray, velocities: np.ndarray) -> float:
    """Mean ``|V_t - W(V_{t-1}, U_{t-1})|`` over a sequence of ``(T, Z, Y, X, C)`` volumes.

    ``velocities (T, Z, Y, X, 3)`` are each frame's own (frame t-1's moves it to frame t).
    """
    volumes = torch.as_tensor(np.asarray(volumes, dtype=np.float32)).permute(0, 4, 1, 2, 3)
    flow = torch.as_tensor(np.asarray(velocities, dtype=np.float32)).permute(0, 4, 1, 2, 3)
    if len(volumes) < 2:
        raise ValueError("temporal_flicker needs at least two frames.")
    warped = semi_lagrangian_warp(volumes[:-1], flow[:-1])
    return float((volumes[1:] - warped).abs().mean())


def multiview_spread(values) -> dict:
    """Spread of a per-view style metric over held-out views: mean, std and relative std."""
    values = np.asarray(list(values), dtype=np.float64)
    mean = float(values.mean())
    return {"mean": mean, "std": float(values.std()), "relative_std": float(values.std() / mean) if mean else 0.0}
