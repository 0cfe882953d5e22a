"""Training objective (paper, Sec. 4.4): histogram, Gram and mean-std style losses, 3D TV, temporal.

Feature maps are ``(B, C, H, W)`` with a foreground mask ``(B, 1, H, W)`` in {0, 1} (rendered value
above 0.001, max-pooled to the feature resolution); style features are ``(C, Hs, Ws)``.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from ..warp import semi_lagrangian_warp


def tone_map(radiance: torch.Tensor, epsilon: float = 1e-3) -> torch.Tensor:
    """Smooth, HDR-safe display transform applied to renders before the feature extractor.

    ``y = ((x / (1 + x)) + eps)^(1/2.2) - eps^(1/2.2)``: Reinhard compression keeps any radiance in
    [0, 1), the 2.2 gamma approximates the display encoding of style photographs, and ``eps`` keeps
    the derivative finite at 0 (a plain power has an infinite slope there). Monotone, smooth,
    bounded. (The paper uses Kettunen et al.'s transform for the same purpose.)
    """
    compressed = radiance.clamp_min(0.0) / (1.0 + radiance.clamp_min(0.0))
    return (compressed + epsilon) ** (1.0 / 2.2) - epsilon ** (1.0 / 2.2)


def histogram_match(values: torch.Tensor, target_sorted: torch.Tensor) -> torch.Tensor:
    """Map ``values (N,)`` onto the distribution of ``target_sorted (M,)``, rank for rank.

    The k-th smallest value becomes the target's quantile at ``k / (N - 1)`` (linear
    interpolation between target samples when ``M != N``; exactly the k-th target when ``M == N``).
    """
    count = values.shape[0]
    if count == 0:
        return values
    order = torch.argsort(values)
    targets = _quantiles(target_sorted, count)
    matched = torch.empty_like(values)
    matched[order] = targets.to(values.dtype)
    return matched


def _quantiles(sorted_values: torch.Tensor, count: int) -> torch.Tensor:
    size = sorted_values.shape[-1]
    if size == count:
        return sorted_values
    position = torch.linspace(0, size - 1, count, device=sorted_values.device, dtype=torch.float64)
    low = position.floor().long().clamp(max=size - 1)
    high = (low + 1).clamp(max=size - 1)
    weight = (position - low).to(sorted_values.dtype)
    return sorted_values[..., low] * (1 - weight) + sorted_values[..., high] * weight


def histogram_loss(features: torch.Tensor, style: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Risser et al.'s histogram loss (paper Eq. 13): masked squared distance to the matched map.

    For each batch item and channel, the masked feature values are histogram-matched to the style
    channel's values; the matched map carries no gradient. Mean over values, summed over channels,
    averaged over the batch.
    """
    batch, channels = features.shape[:2]
    if style.shape[0] != channels:
        raise ValueError(f"Style has {style.shape[0]} channels, features {channels}.")
    style_sorted = torch.sort(style.reshape(channels, -1).detach(), dim=1).values
    flat = features.reshape(batch, channels, -1)
    keep = None if mask is None else mask.reshape(batch, -1) > 0.5
    total = features.new_zeros(())
    for item in range(batch):
        values = flat[item] if keep is None else flat[item][:, keep[item]]
        if values.shape[1] == 0:
            continue
        with torch.no_grad():
            order = torch.argsort(values, dim=1)
            matched = torch.empty_like(values)
            matched.scatter_(1, order, _quantiles(style_sorted, values.shape[1]).to(values.dtype))
        total = total + ((values - matched) ** 2).mean(dim=1).sum()
    return total / batch


def gram_loss(features: torch.Tensor, style: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Squared Frobenius distance between masked Gram matrices (normalised by the value count)."""
    def gram(values: torch.Tensor) -> torch.Tensor:  # (C, N)
        return values @ values.transpose(0, 1) / max(values.shape[1], 1)

    target = gram(style.reshape(style.shape[0], -1))
    return _per_item(features, mask, lambda values: ((gram(values) - target) ** 2).sum())


def mean_std_loss(features: torch.Tensor, style: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Squared distance of masked channel means and standard deviations to the style's."""
    style_flat = style.reshape(style.shape[0], -1)
    mean, std = style_flat.mean(1), style_flat.std(1, unbiased=False)
    return _per_item(
        features, mask,
        lambda values: ((values.mean(1) - mean) ** 2).sum() + ((values.std(1, unbiased=False) - std) ** 2).sum(),
    )


def _per_item(features, mask, loss_of_values):
    batch, channels = features.shape[:2]
    flat = features.reshape(batch, channels, -1)
    total = features.new_zeros(())
    for item in range(batch):
        values = flat[item] if mask is None else flat[item][:, mask.reshape(batch, -1)[item] > 0.5]
        if values.shape[1]:
            total = total + loss_of_values(values)
    return total / batch


def tv_loss(volume: torch.Tensor) -> torch.Tensor:
    """3D total variation (paper Eq. 15): mean squared finite differences along x, y and z.

    ``volume`` is ``(B, C, D, H, W)``.
    """
    if volume.dim() != 5:
        raise ValueError(f"tv_loss expects (B, C, D, H, W), got {tuple(volume.shape)}.")
    return sum(
        (torch.diff(volume, dim=axis) ** 2).mean() if volume.shape[axis] > 1 else volume.new_zeros(())
        for axis in (2, 3, 4)
    )


def temporal_loss(current: torch.Tensor, previous: torch.Tensor, velocity: torch.Tensor) -> torch.Tensor:
    """``mean |V - W(V', U)|^2`` (paper Eq. 16), ``W`` the semi-Lagrangian warp by ``U``.

    ``current`` and ``previous`` are ``(B, C, D, H, W)`` albedo volumes of frames t+1 and t;
    ``velocity (B, 3, D, H, W)`` is frame t's, in voxels per frame, ``(x, y, z)``.
    """
    return ((current - semi_lagrangian_warp(previous, velocity)) ** 2).mean()


def render_mask(images: torch.Tensor, threshold: float = 1e-3) -> torch.Tensor:
    """Foreground mask ``(B, 1, H, W)`` of rendered images ``(B, 3, H, W)``: any channel above ``threshold``."""
    return (images.detach().amax(dim=1, keepdim=True) > threshold).to(images.dtype)


def pool_mask(mask: torch.Tensor, size: tuple[int, int]) -> torch.Tensor:
    """Max-pool a mask to a feature map's ``(H, W)`` (paper: masks are max-pooled to each level)."""
    if tuple(mask.shape[-2:]) == tuple(size):
        return mask
    return F.adaptive_max_pool2d(mask, size)
