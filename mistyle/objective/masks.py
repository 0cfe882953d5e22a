"""Foreground masks of rendered images: which pixels see the medium.

The mask is taken without gradient from the linear render (any channel above
``conventions.FOREGROUND_THRESHOLD``) and max-pooled to each feature level (paper Sec. 4.4).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from ..conventions import FOREGROUND_THRESHOLD
from ..tone import tone_map


def render_mask(images: torch.Tensor, threshold: float = FOREGROUND_THRESHOLD) -> torch.Tensor:
    """Foreground mask ``(B, 1, H, W)`` of rendered images ``(B, 3, H, W)``: any channel above ``threshold``."""
    return (images.detach().amax(dim=1, keepdim=True) > threshold).to(images.dtype)


def pool_mask(mask: torch.Tensor, size: tuple[int, int]) -> torch.Tensor:
    """Max-pool a mask to a feature map's ``(H, W)`` (paper: masks are max-pooled to each level)."""
    if tuple(mask.shape[-2:]) == tuple(size):
        return mask
    return F.adaptive_max_pool2d(mask, size)


BODY_THRESHOLD = 0.5


def body_mask(white_render: torch.Tensor, threshold: float = BODY_THRESHOLD) -> torch.Tensor:
    """The medium's body ``(B, 1, H, W)``: pixels where a render of the same view with a white albedo
    ``(B, 3, H, W)`` (linear) is brighter than ``threshold`` on display.

    Matching a style's colours only there keeps the thin, dark fringes of a medium (which no albedo
    can make bright) from soaking up the style's dark colours while the body stays pale
    (measured: ``docs/decisions/2026-11-25-style-fidelity-study.md``).
    """
    return (tone_map(white_render.detach()).mean(dim=1, keepdim=True) > threshold).to(white_render.dtype)
