"""Style-match metrics for experiments and training logs.

Images are numpy or torch ``(H, W, 3)``. Renders are linear radiance and go through the training
tone curve (``mistyle.tone``) so they are compared with style images in display space.
"""

from __future__ import annotations

import numpy as np
import torch

from ..conventions import FOREGROUND_THRESHOLD
from ..memo import kept
from ..tone import display
from ..warp import semi_lagrangian_warp
from .losses import scaled_patches


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


def sliced_wasserstein(a: np.ndarray, b: np.ndarray, projections: int = 128, seed: int = 0, order: int = 2) -> float:
    """Sliced Wasserstein-``order`` distance between point sets ``(N, D)`` and ``(M, D)`` (RGB: D = 3).

    ``(mean over random unit directions of W_p^p between the 1D projections)^(1/p)``; quantiles are
    compared at a common count, so the sets need not have equal sizes. Sets of more than
    ``MAX_METRIC_POINTS`` points are subsampled first.
    """
    if order not in (1, 2):
        raise ValueError(f"sliced_wasserstein supports order 1 or 2, got {order}.")
    rng = np.random.default_rng(seed)
    a, b = (np.asarray(bounded_points(points, rng), dtype=np.float64) for points in (a, b))
    if len(a) == 0 or len(b) == 0:
        raise ValueError("sliced_wasserstein needs non-empty point sets (did the render see any medium?).")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"sliced_wasserstein needs points of one dimension, got {a.shape[1]} and {b.shape[1]}.")
    directions = np.random.default_rng(seed).normal(size=(projections, a.shape[1]))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    count = max(len(a), len(b))
    levels = (np.arange(count) + 0.5) / count
    qa = _sorted_quantiles(np.sort(a @ directions.T, axis=0), levels)
    qb = _sorted_quantiles(_sorted_projections(b, directions), levels)
    if order == 1:
        return float(np.mean(np.abs(qa - qb)))
    return float(np.sqrt(np.mean((qa - qb) ** 2)))


def _sorted_projections(points: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """``points @ directions.T`` sorted down each column (the second set of ``sliced_wasserstein``, the
    style: ``memo.kept``)."""
    return kept("sorted projections", (points, directions), lambda: np.sort(points @ directions.T, axis=0))


def bounded_points(points, rng: np.random.Generator, limit: int = MAX_METRIC_POINTS) -> np.ndarray:
    """``points`` as ``(N, D)`` (``(N, 3)`` for images), subsampled to ``limit`` rows when larger
    (no copy otherwise)."""
    points = np.asarray(points)
    points = points.reshape(-1, 3) if points.ndim != 2 else points
    if len(points) <= limit:
        return points
    return points[np.sort(rng.choice(len(points), limit, replace=False))]


def _sorted_quantiles(sorted_values: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Quantiles at ``levels`` in (0, 1) of each column of column-sorted ``(N, P)`` values (linear): the
    values themselves at their own count's levels."""
    if len(levels) == len(sorted_values):
        return sorted_values
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


# ---------------------------------------------------------------------------- style fidelity
# The three numbers of the fidelity benchmark (DESIGN.md, "Measuring style fidelity"): how much of
# a style's colours, local patterns and hues reach the render. Renders are linear radiance; only
# their foreground pixels (any channel above FOREGROUND_THRESHOLD) count, in display space.

PATCH_SIZE = 5
PATCH_SCALES = (1, 2, 4)
MAX_PATCHES = 1 << 14
"""Patch sets are subsampled to this many patches per scale: 75-D points x 128 projections stay cheap
(about 0.1 s), and the distance moves by under 2% against 4x as many (``tests/test_fidelity.py``)."""
HUE_CLUSTERS = 5


def foreground_mask(render: np.ndarray, threshold: float = FOREGROUND_THRESHOLD) -> np.ndarray:
    """``(H, W)`` bool: the pixels of a linear render ``(H, W, 3)`` that see the medium."""
    return np.asarray(render).max(axis=-1) > threshold


def image_patches(image: np.ndarray, mask: np.ndarray | None, scale: int, size: int = PATCH_SIZE) -> np.ndarray:
    """``size x size`` colour patches ``(N, size*size*3)`` of ``image (H, W, 3)`` downsampled by ``scale``
    (box filter); with ``mask (H, W)``, only patches whose every downsampled pixel is wholly inside it."""
    tensor = torch.from_numpy(np.ascontiguousarray(image, dtype=np.float32)).permute(2, 0, 1)[None]
    inside = None if mask is None else torch.from_numpy(np.ascontiguousarray(mask, dtype=np.float32))[None, None]
    return scaled_patches(tensor, inside, scale, size).numpy()


def patch_swd(
    images: list[np.ndarray], masks: list[np.ndarray] | None, style: np.ndarray, scales=PATCH_SCALES, seed: int = 0
) -> float:
    """Sliced Wasserstein-1 between the 5x5 patches of display ``images`` (inside ``masks``) and the
    style's, averaged over ``scales``. ``nan`` when no scale has a patch wholly inside the foreground."""
    rng = np.random.default_rng(seed)
    distances = []
    for scale in scales:
        ours = [
            image_patches(image, None if masks is None else mask, scale)
            for image, mask in zip(images, masks if masks is not None else [None] * len(images))
        ]
        ours = np.concatenate(ours)
        theirs = image_patches(style, None, scale)
        if len(ours) == 0 or len(theirs) == 0:
            continue
        distances.append(
            sliced_wasserstein(
                bounded_points(ours, rng, MAX_PATCHES), bounded_points(theirs, rng, MAX_PATCHES), seed=seed, order=1
            )
        )
    return float(np.mean(distances)) if distances else float("nan")


def srgb_to_lab(rgb: np.ndarray) -> np.ndarray:
    """CIELab (D65) of sRGB-encoded colours ``(..., 3)`` in [0, 1]."""
    rgb = np.clip(np.asarray(rgb, dtype=np.float64), 0, 1)
    linear = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    to_xyz = np.array(
        [[0.4124564, 0.3575761, 0.1804375], [0.2126729, 0.7151522, 0.0721750], [0.0193339, 0.1191920, 0.9503041]]
    )
    xyz = linear @ to_xyz.T / np.array([0.95047, 1.0, 1.08883])
    delta = 6 / 29
    f = np.where(xyz > delta**3, np.cbrt(xyz), xyz / (3 * delta**2) + 4 / 29)
    return np.stack([116 * f[..., 1] - 16, 500 * (f[..., 0] - f[..., 1]), 200 * (f[..., 1] - f[..., 2])], axis=-1)


def kmeans(points: np.ndarray, clusters: int, seed: int = 0, iterations: int = 50) -> np.ndarray:
    """Lloyd's k-means with k-means++ seeding: centres ``(clusters, D)`` of ``points (N, D)``."""
    rng = np.random.default_rng(seed)
    points = np.asarray(points, dtype=np.float64)
    centres = [points[rng.integers(len(points))]]
    for _ in range(1, clusters):
        nearest = np.min(((points[:, None] - np.array(centres)[None]) ** 2).sum(-1), axis=1)
        total = nearest.sum()
        centres.append(
            points[rng.choice(len(points), p=nearest / total)] if total > 0 else points[rng.integers(len(points))]
        )
    centres = np.array(centres)
    for _ in range(iterations):
        labels = np.argmin(((points[:, None] - centres[None]) ** 2).sum(-1), axis=1)
        moved = np.array([points[labels == k].mean(0) if np.any(labels == k) else centres[k] for k in range(clusters)])
        if np.allclose(moved, centres):
            break
        centres = moved
    return centres


def hue_coverage(pixels: np.ndarray, style: np.ndarray, clusters: int = HUE_CLUSTERS, seed: int = 0) -> float:
    """How much of the style's hue distribution display ``pixels (N, 3)`` cover, in [0, 1].

    k-means of the style's CIELab (a*, b*) into ``clusters`` hue clusters; the render's pixels go to
    the nearest centre; the sum over clusters of min(style share, render share). 1 when the render
    uses the style's hues in the style's proportions; a render of one hue scores that hue's share.
    """
    rng = np.random.default_rng(seed)
    style_ab = srgb_to_lab(bounded_points(np.asarray(style).reshape(-1, 3), rng, 1 << 16))[:, 1:]
    ours_ab = srgb_to_lab(bounded_points(np.asarray(pixels).reshape(-1, 3), rng, 1 << 16))[:, 1:]
    if len(ours_ab) == 0:
        return 0.0
    centres = kept("hue clusters", (style_ab, np.array([clusters, seed])), lambda: kmeans(style_ab, clusters, seed))

    def shares(points):
        labels = np.argmin(((points[:, None] - centres[None]) ** 2).sum(-1), axis=1)
        return np.bincount(labels, minlength=clusters) / len(points)

    return float(np.minimum(shares(style_ab), shares(ours_ab)).sum())


def style_fidelity(renders: list[np.ndarray], style: np.ndarray, masks: list[np.ndarray] | None = None) -> dict:
    """The benchmark's metrics of linear ``renders`` (views of one volume, ``(H, W, 3)`` each) against a
    display-space ``style (H, W, 3)``: ``rgb_swd`` (sliced W1 of foreground pixel colours),
    ``patch_swd`` (sliced W1 of 5x5 foreground patches at scales 1, 1/2, 1/4, averaged),
    ``hue_coverage`` and ``structure`` (oriented multi-scale gradient statistics inside the foreground,
    ``objective.structure``; lower is closer). Pixels of all views are pooled. ``masks``: the
    foreground of each render, where not its own (``foreground_mask``)."""
    from .structure import structure_distance

    masks = [foreground_mask(render) for render in renders] if masks is None else masks
    if not any(mask.any() for mask in masks):
        raise ValueError("style_fidelity: no render sees the medium (every pixel is background).")
    shown = [display(render) for render in renders]
    pixels = np.concatenate([image[mask] for image, mask in zip(shown, masks)])
    style = np.asarray(style, dtype=np.float32)
    return {
        "rgb_swd": sliced_wasserstein(pixels, style.reshape(-1, 3), order=1),
        "patch_swd": patch_swd(shown, masks, style),
        "hue_coverage": hue_coverage(pixels, style),
        "structure": structure_distance(shown, masks, style),
    }


EXPOSURE_RANGE = (1.0 / 256.0, 256.0)


def matched_exposure(renders: list[np.ndarray], style: np.ndarray, masks: list[np.ndarray] | None = None) -> float:
    """The one factor ``k`` (in ``EXPOSURE_RANGE``) by which linear ``renders`` (views of one volume) are
    scaled so that their foreground's mean display value (over the three channels) is the style's: the
    exposure a photographer would pick to show the medium as bright as the picture. A thin smoke under
    the benchmark's light shows darker than most pictures whatever its albedo; at this exposure the
    colour and patch distances compare colours and patterns, not how much light the medium can
    scatter (``experiments/exposure_study.py``). ``masks``: the renders' foregrounds, where known."""
    masks = [foreground_mask(render) for render in renders] if masks is None else masks
    pixels = np.concatenate([np.asarray(render)[mask] for render, mask in zip(renders, masks)])
    if not len(pixels):
        raise ValueError("matched_exposure: no render sees the medium (every pixel is background).")
    wanted = float(np.asarray(style, np.float32).mean())
    low, high = (float(np.log2(bound)) for bound in EXPOSURE_RANGE)
    for _ in range(40):  # the mean display value rises with the exposure: bisect its log
        middle = 0.5 * (low + high)
        if float(display(pixels * 2.0**middle).mean()) < wanted:
            low = middle
        else:
            high = middle
    return float(2.0 ** (0.5 * (low + high)))


def exposure_matched_fidelity(renders: list[np.ndarray], style: np.ndarray) -> tuple[dict, float]:
    """``style_fidelity`` of ``renders`` at their ``matched_exposure``, over their foreground as rendered:
    ``(metrics, exposure)``."""
    masks = [foreground_mask(render) for render in renders]
    exposure = matched_exposure(renders, style, masks)
    return style_fidelity([np.asarray(render) * exposure for render in renders], style, masks), exposure


def correlation_length(field: np.ndarray, mask: np.ndarray) -> float:
    """The lag (voxels) at which the radially averaged autocorrelation of ``field`` inside ``mask``
    falls to 1/2, linearly interpolated between shells of lags one voxel wide (each at its mean lag).

    The autocorrelation at lag r pools every pair of voxels r apart with both inside the mask
    (zero-padded FFTs of the masked, mean-removed field and of the mask), so the medium's outline does
    not count as structure. ``inf`` when it never falls to 1/2 within half the grid.
    """
    mask = np.asarray(mask, dtype=np.float64)
    if mask.shape != np.shape(field) or not mask.any():
        raise ValueError(
            f"correlation_length: need a non-empty mask of the field's shape {np.shape(field)}, "
            f"got {mask.shape} with {int(np.count_nonzero(mask))} voxels inside."
        )
    values = np.where(mask > 0, np.asarray(field, np.float64), 0.0)
    values = (values - values.sum() / mask.sum()) * mask
    padded = [2 * n for n in values.shape]
    axes = list(range(values.ndim))

    def autocorrelation(x):
        spectrum = np.fft.rfftn(x, padded, axes=axes)
        return np.fft.irfftn(spectrum * np.conj(spectrum), padded, axes=axes)

    products, pairs = autocorrelation(values), autocorrelation(mask)
    lags = np.sqrt(
        sum(
            np.minimum(i, n - i) ** 2
            for i, n in zip(np.meshgrid(*[np.arange(n) for n in padded], indexing="ij"), padded)
        )
    )
    shells = np.rint(lags).astype(int)
    limit = min(values.shape) // 2
    keep = (shells <= limit) & (pairs > 0.5)  # lags with at least one pair of voxels inside the mask
    pooled = np.bincount(shells[keep], products[keep], minlength=limit + 1)
    counted = np.bincount(shells[keep], pairs[keep], minlength=limit + 1)
    curve = pooled / np.maximum(counted, 1e-12)
    curve = curve / curve[0]
    mean_lag = np.bincount(shells[keep], (lags * pairs)[keep], minlength=limit + 1) / np.maximum(counted, 1e-12)
    below = np.nonzero(curve < 0.5)[0]
    if len(below) == 0:
        return float("inf")
    r = int(below[0])
    return float(np.interp(0.5, [curve[r], curve[r - 1]], [mean_lag[r], mean_lag[r - 1]]))
