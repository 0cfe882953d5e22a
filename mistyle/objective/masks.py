"""Foreground masks of rendered images: which pixels see the medium.

The mask is taken without gradient from the linear render (any channel above
``conventions.FOREGROUND_THRESHOLD``) and max-pooled to each feature level (paper Sec. 4.4).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from ..conventions import FOREGROUND_THRESHOLD


def render_mask(images: torch.Tensor, threshold: float = FOREGROUND_THRESHOLD) -> torch.Tensor:
    """Foreground mask ``(B, 1, H, W)`` of rendered images ``(B, 3, H, W)``: any channel above ``threshold``."""
    return (images.detach().amax(dim=1, keepdim=True) > threshold).to(images.dtype)


def pool_mask(mask: torch.Tensor, size: tuple[int, int]) -> torch.Tensor:
    """Max-pool a mask to a feature map's ``(H, W)`` (paper: masks are max-pooled to each level)."""
    if tuple(mask.shape[-2:]) == tuple(size):
        return mask
    return F.adaptive_max_pool2d(mask, size)
