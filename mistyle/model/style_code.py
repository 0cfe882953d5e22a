"""The style code: what the stylizing kernel predictor reads of a style image beyond feature moments.

The paper's SKP sees the channel means and standard deviations of each feature level. Moments of a
fixed filter bank hardly tell two paintings apart (issue: style fidelity II), so with
``SKPNConfig.style_code = "quantiles"`` every predictor also reads one code vector per style made of
the distributions that the sliced objective and the fidelity benchmark compare:

* **colours**: ``QUANTILES`` quantiles of the pixels' projections on ``COLOUR_DIRECTIONS`` fixed
  directions of RGB (the three axes, grey, two opponent axes, and fixed random ones);
* **patterns**: ``PATCH_QUANTILES`` quantiles of 5x5 patches, at scales 1, 1/2 and 1/4, projected
  on ``PATCH_DIRECTIONS`` fixed random directions with their per-channel mean removed, so they
  respond to structure (edges, strokes, grain) rather than to colour.

A sorted projection is the 1-D optimal-transport coordinate of a distribution, so codes of two
styles differ by (a sampled, sliced) Wasserstein distance, and a convex mix of codes is a
displacement interpolation of the styles' slices. Images ``(B, 3, S, S)`` in display [0, 1] give
codes ``(B, CODE_SIZE)``.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

QUANTILES = 16
PATCH_QUANTILES = 8
PATCH_SIZE = 5
PATCH_SCALES = (1, 2, 4)
COLOUR_DIRECTIONS = 12
PATCH_DIRECTIONS = 16
CODE_SIZE = COLOUR_DIRECTIONS * QUANTILES + len(PATCH_SCALES) * PATCH_DIRECTIONS * PATCH_QUANTILES
_SEED = 20211


def _colour_directions() -> torch.Tensor:
    """``(3, COLOUR_DIRECTIONS)`` unit vectors: R, G, B, grey, two opponent axes, then fixed random ones."""
    fixed = torch.tensor([[1.0, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1], [1, -1, 0], [1, 1, -2]])
    extra = torch.randn(COLOUR_DIRECTIONS - len(fixed), 3, generator=torch.Generator().manual_seed(_SEED))
    directions = torch.cat([fixed, extra])
    return (directions / directions.norm(dim=1, keepdim=True)).T.contiguous()


def _patch_directions() -> torch.Tensor:
    """``(3 * PATCH_SIZE^2, PATCH_DIRECTIONS)``: random unit vectors with zero mean within each colour channel."""
    directions = torch.randn(PATCH_DIRECTIONS, 3, PATCH_SIZE**2, generator=torch.Generator().manual_seed(_SEED + 1))
    directions = directions - directions.mean(dim=2, keepdim=True)
    directions = directions.flatten(1)
    return (directions / directions.norm(dim=1, keepdim=True)).T.contiguous()


COLOUR_BASIS = _colour_directions()
PATCH_BASIS = _patch_directions()


def _sorted_quantiles(values: torch.Tensor, count: int) -> torch.Tensor:
    """``(B, D, count)`` quantiles at ``(i + 1/2) / count`` of ``values (B, N, D)`` along N."""
    ordered = torch.sort(values, dim=1).values
    positions = ((torch.arange(count, dtype=torch.float32) + 0.5) / count * (values.shape[1] - 1)).round().long()
    return ordered[:, positions.to(values.device)].transpose(1, 2)


def style_code(images: torch.Tensor) -> torch.Tensor:
    """The quantile code ``(B, CODE_SIZE)`` of style images ``(B, 3, S, S)`` (see the module docstring)."""
    if images.dim() != 4 or images.shape[1] != 3:
        raise ValueError(f"style images must be (B, 3, S, S), got {tuple(images.shape)}.")
    if min(images.shape[-2:]) < PATCH_SIZE * max(PATCH_SCALES):
        raise ValueError(
            f"style images must be at least {PATCH_SIZE * max(PATCH_SCALES)} pixels on a side for the style code."
        )
    images = images.float()
    batch = images.shape[0]
    pixels = images.flatten(2).transpose(1, 2)  # (B, N, 3)
    parts = [_sorted_quantiles(pixels @ COLOUR_BASIS.to(images), QUANTILES).flatten(1)]
    for scale in PATCH_SCALES:
        scaled = F.avg_pool2d(images, scale) if scale > 1 else images
        patches = F.unfold(scaled, PATCH_SIZE).transpose(1, 2)  # (B, N, 75)
        # Patch projections spread about 1/sqrt(75) as far as colours; rescale so both parts weigh alike.
        projected = patches @ PATCH_BASIS.to(images) * math.sqrt(PATCH_SIZE)
        parts.append(_sorted_quantiles(projected, PATCH_QUANTILES).flatten(1))
    return torch.cat(parts, dim=1).reshape(batch, CODE_SIZE)
