"""Density-aware instance normalisation (DAIN, paper Sec. 4.2).

Instance normalisation over a volume mixes the empty space around smoke into the statistics.
DAIN weights each voxel by a soft occupancy mask ``m = 1 - exp(-lambda * density^2)`` (lambda = 100),
max-pooled to the feature map's resolution, and normalises with the masked mean and variance:

    mu = sum(m x) / sum(m),   var = sum(m (x - mu)^2) / sum(m),   y = gamma (x - mu) / sqrt(var + eps) + beta

with ``eps = 1e-5`` and ``gamma, beta`` per channel (from the stylizing kernel). An all-zero mask
falls back to zero mean and unit variance, so an empty density never produces NaN.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

DAIN_LAMBDA = 100.0
EPSILON = 1e-5


def density_mask(
    density: torch.Tensor, size: tuple[int, int, int] | None = None, lam: float = DAIN_LAMBDA
) -> torch.Tensor:
    """``1 - exp(-lambda density^2)`` for ``density (B, 1, D, H, W)``, max-pooled to ``size`` if given."""
    mask = 1.0 - torch.exp(-lam * density**2)
    if size is not None and tuple(mask.shape[2:]) != tuple(size):
        mask = F.adaptive_max_pool3d(mask, size)
    return mask


def masked_statistics(features: torch.Tensor, mask: torch.Tensor | None) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-instance, per-channel mean and variance ``(B, C, 1, 1, 1)`` weighted by ``mask (B, 1, D, H, W)``.

    Computed in float32 whatever the autocast precision: the weighted sums are two matrix products
    (``bmm``) of the features, shifted by their plain mean (no gradient) so that ``E[x^2] - E[x]^2``
    does not cancel when a channel's mean is large against its spread.
    """
    with torch.autocast(features.device.type, enabled=False):
        batch, channels = features.shape[:2]
        if mask is None:
            flat = features.float().flatten(2)
            variance, mean = torch.var_mean(flat, dim=2, keepdim=True, correction=0)
            return mean[..., None, None], variance[..., None, None]
        # Voxels as rows, channels as columns: (B, N, C); a view for channels-last features, one copy otherwise.
        rows = features.permute(0, 2, 3, 4, 1).reshape(batch, -1, channels)
        # Any value near the mean serves as the shift; a strided subsample's mean spares a full pass.
        shift = rows[:, :: max(1, rows.shape[1] // 4096)].float().mean(1, keepdim=True).detach()
        centred = rows - shift  # float32 (type promotion), one pass
        weight = mask.float().expand(-1, 1, *features.shape[2:]).reshape(batch, 1, -1)
        total = weight.sum(2, keepdim=True)
        safe_total = total.clamp_min(1e-12)
        first = torch.bmm(weight, centred) / safe_total
        second = torch.bmm(weight, centred * centred) / safe_total
        first, second, shift, total = (t.transpose(1, 2) for t in (first, second, shift, total))
        mean, variance = first + shift, (second - first * first).clamp_min(0.0)
        empty = total <= 1e-12
        mean = torch.where(empty, torch.zeros_like(mean), mean)
        variance = torch.where(empty, torch.ones_like(variance), variance)
        return mean[..., None, None], variance[..., None, None]


def dain(features: torch.Tensor, mask: torch.Tensor | None, gamma: torch.Tensor, beta: torch.Tensor) -> torch.Tensor:
    """Normalise ``features (B, C, D, H, W)`` with masked statistics, then ``gamma, beta (B, C)``.

    ``mask=None`` is plain instance normalisation (for the paper's DAIN-vs-IN ablation). The
    normalisation and the affine map are folded into one ``x * scale + shift`` per channel. The output
    keeps ``features``' memory format (contiguous or channels-last).
    """
    mean, variance = masked_statistics(features, mask)
    scale = gamma.float()[..., None, None, None] * torch.rsqrt(variance + EPSILON)
    shift = beta.float()[..., None, None, None] - mean * scale
    # Not addcmul: multiply-then-add_ runs twice as fast on the CPU, and autograd allows add_ on the
    # fresh product.
    return (features * scale.to(features.dtype)).add_(shift.to(features.dtype))


def masked_moments(features: torch.Tensor, mask: torch.Tensor | None) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-instance mean ``(B, C)`` and covariance ``(B, C, C)`` of ``features (B, C, D, H, W)`` over
    its voxels, weighted by ``mask`` as ``masked_statistics`` weighs them (None: unweighted). With them,
    DAIN after a 1x1x1 kernel has a closed form (``dain_of_mixed``), so features that do not change can
    be summarised once."""
    with torch.autocast(features.device.type, enabled=False):
        batch, channels = features.shape[:2]
        rows = features.float().permute(0, 2, 3, 4, 1).reshape(batch, -1, channels)
        shift = rows[:, :: max(1, rows.shape[1] // 4096)].mean(1, keepdim=True)
        centred = rows - shift
        if mask is None:
            weight = torch.ones((batch, 1, rows.shape[1]), device=features.device)
        else:
            weight = mask.float().expand(-1, 1, *features.shape[2:]).reshape(batch, 1, -1)
        total = weight.sum(2, keepdim=True)
        if bool((total <= 1e-12).any()):
            raise ValueError("masked_moments needs a mask with some weight in every instance.")
        first = torch.bmm(weight, centred) / total  # (B, 1, C)
        second = torch.bmm(centred.transpose(1, 2), centred * weight.transpose(1, 2)) / total  # (B, C, C)
        covariance = second - first.transpose(1, 2) * first
        return (first + shift)[:, 0], covariance


def dain_of_mixed(
    mean: torch.Tensor, covariance: torch.Tensor, mix: torch.Tensor, gamma: torch.Tensor, beta: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """DAIN of the channel mix ``y = mix @ x`` as an affine map of ``x``: ``(scale (B, C, C), shift (B, C))``
    with ``dain(mix @ x, mask, gamma, beta) = scale @ x + shift``, where ``mean (B, C)`` and ``covariance
    (B, C, C)`` are ``masked_moments(x, mask)`` and ``mix (B, C, C)`` a 1x1x1 kernel's weight. Differentiable
    in ``mix``, ``gamma`` and ``beta``."""
    mixed_mean = torch.einsum("boi,bi->bo", mix, mean)
    variance = torch.einsum("boi,bij,boj->bo", mix, covariance, mix).clamp_min(0.0)
    factor = gamma.float() * torch.rsqrt(variance + EPSILON)
    return factor[..., None] * mix, beta.float() - factor * mixed_mean
