"""The paper's losses (Sec. 4.4: histogram, Gram and mean-std style losses, 3D TV, temporal) and the
sliced-Wasserstein loss on point sets (pixel colours, pixel patches) with its masked patch extraction.

Feature maps are ``(B, C, H, W)`` with a foreground mask ``(B, 1, H, W)`` in {0, 1}
(``masks.render_mask``, max-pooled to the feature resolution); style features are ``(C, Hs, Ws)``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import torch
import torch.nn.functional as F

from ..warp import semi_lagrangian_warp


def _quantiles(sorted_values: torch.Tensor, count: int) -> torch.Tensor:
    size = sorted_values.shape[-1]
    if size == count:
        return sorted_values
    position = torch.linspace(0, size - 1, count, device=sorted_values.device, dtype=torch.float64)
    low = position.floor().long().clamp(max=size - 1)
    high = (low + 1).clamp(max=size - 1)
    weight = (position - low).to(sorted_values.dtype)
    axis = sorted_values.dim() - 1  # index_select: several times faster than advanced indexing on the CPU
    low_values, high_values = sorted_values.index_select(axis, low), sorted_values.index_select(axis, high)
    return low_values * (1 - weight) + high_values * weight


def _sorted_rows(values: torch.Tensor) -> torch.Tensor:
    """``values (P, N)`` sorted along N, without gradient: by NumPy on the CPU, where it sorts about twice
    as fast as ``torch.sort`` (a look's fit sorts a target's 8192 projections four times a step)."""
    if values.device.type != "cpu" or values.dtype not in (torch.float32, torch.float64):
        return torch.sort(values, dim=1).values
    return torch.from_numpy(np.sort(values.numpy(), axis=1))


def _argsort_rows(values: torch.Tensor) -> torch.Tensor:
    """The order that sorts each row of ``values (P, N)``, without gradient: by NumPy on the CPU, where
    it is several times faster than ``torch.argsort`` (a solid texture's synthesis spent most of each step
    in ``torch.sort`` of its 8192 x 64 projections)."""
    if values.device.type != "cpu" or values.dtype not in (torch.float32, torch.float64):
        return torch.argsort(values, dim=1)
    return torch.from_numpy(np.argsort(values.detach().numpy(), axis=1))


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
        features,
        mask,
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


class ProjectedTarget(NamedTuple):
    """A target point set ``(M, D)`` projected once on a pool of random unit directions ``(D, P)``, each
    projection sorted ``(P, M)`` (``project_target``): what ``sliced_wasserstein_loss`` compares with
    when the directions of every call are drawn from the pool rather than afresh."""

    directions: torch.Tensor
    sorted: torch.Tensor

    @property
    def shape(self) -> tuple:
        return self.sorted.shape[1], self.directions.shape[0]


@torch.no_grad()
def project_target(target: torch.Tensor, pool: int, generator: torch.Generator | None = None) -> ProjectedTarget:
    """``target (M, D)``'s sorted projections on ``pool`` random unit directions."""
    directions = torch.randn(target.shape[1], pool, generator=generator).to(target)
    directions = directions / directions.norm(dim=0, keepdim=True)
    return ProjectedTarget(directions, _sorted_rows((target @ directions).T.contiguous()))


def projected_target(points, target, projections: int, generator=None):
    """A sliced loss's ``projections`` unit directions ``(D, P)`` and the target's projections on them, each
    row sorted ``(P, M)``: drawn from a ``ProjectedTarget``'s pool (no repeats within a call), or fresh
    directions with ``target``'s points projected and sorted here."""
    if isinstance(target, ProjectedTarget):
        chosen = torch.randperm(target.directions.shape[1], generator=generator)[:projections]
        return target.directions[:, chosen].to(points), target.sorted[chosen].to(points)
    directions = torch.randn(points.shape[1], projections, generator=generator).to(points)
    directions = directions / directions.norm(dim=0, keepdim=True)
    with torch.no_grad():
        theirs = _sorted_rows((target.to(points) @ directions).T.contiguous())
    return directions, theirs


def sliced_wasserstein_loss(
    points: torch.Tensor,
    target: torch.Tensor | ProjectedTarget,
    projections: int = 64,
    generator: torch.Generator | None = None,
) -> torch.Tensor:
    """Squared sliced 2-Wasserstein distance between point sets ``(N, D)`` and ``(M, D)`` (Heitz et al. 2021).

    Both sets are projected on ``projections`` random unit directions; each sorted projection of
    ``points`` is compared with the target's quantiles at the same ranks (the target carries no
    gradient, so the sets need not have equal sizes). Unlike a per-channel histogram loss, random
    directions couple the channels: a render with the style's red and blue but not its purple
    pixels is penalised. A ``ProjectedTarget`` gives the directions a pool to be drawn from (without
    repeats within a call) and its sorted projections, which are then not sorted again.
    """
    if points.shape[1] != target.shape[1]:
        raise ValueError(f"Point sets of dimension {points.shape[1]} and {target.shape[1]}.")
    if points.shape[0] == 0:
        return points.new_zeros(())
    directions, theirs = projected_target(points, target, projections, generator)
    ours = (points @ directions).T  # (P, N)
    with torch.no_grad():
        # Each projected point is compared with the target's quantile at its own rank: the sum over the
        # sorted pairs, without sorting (and back-propagating through a sort of) the points.
        matched = torch.empty_like(ours)
        matched.scatter_(1, _argsort_rows(ours.contiguous()), _quantiles(theirs, ours.shape[1]).to(ours))
    return ((ours - matched) ** 2).mean() * points.shape[1]


def masked_patches(images: torch.Tensor, mask: torch.Tensor | None, size: int) -> torch.Tensor:
    """``size x size`` patches ``(N, C*size*size)`` of ``images (B, C, H, W)``; with ``mask (B, 1, H, W)``,
    only the patches wholly inside it. Images smaller than a patch give none."""
    if min(images.shape[-2:]) < size:
        return images.new_zeros((0, images.shape[1] * size * size))
    patches = F.unfold(images, size).transpose(1, 2).reshape(-1, images.shape[1] * size * size)
    if mask is None:
        return patches
    inside = F.unfold(mask, size).amin(dim=1).reshape(-1) > 0.5
    return patches[inside]


def scaled_patches(images: torch.Tensor, mask: torch.Tensor | None, scale: int, size: int) -> torch.Tensor:
    """``masked_patches`` of ``images (B, C, H, W)`` box-downsampled by ``scale``; the mask is min-pooled, so
    a patch counts only when every pixel under it lies inside the mask."""
    if min(images.shape[-2:]) < scale * size:  # fewer than ``size`` pixels a side once downsampled: no patch
        return images.new_zeros((0, images.shape[1] * size * size))
    if scale > 1:
        images = F.avg_pool2d(images, scale)
        mask = None if mask is None else -F.max_pool2d(-mask, scale)
    return masked_patches(images, mask, size)


OPPONENT = ((1 / 3, 1 / 3, 1 / 3), (1 / 2, -1 / 2, 0.0), (1 / 4, 1 / 4, -1 / 2))
"""Display RGB -> luminance ``(R + G + B) / 3`` and the colour-opponent channels ``(R - G) / 2`` and
``(R + G - 2B) / 4``: what the structure metric (``objective.structure``) and the look's gradient term
compare."""


def gradient_points(images: torch.Tensor, mask: torch.Tensor | None, scale: int) -> torch.Tensor:
    """``(N, 6)``: the central-difference gradients ``(d/dx, d/dy)`` of the luminance and the two opponent
    channels (``OPPONENT``) of ``images (B, 3, H, W)`` box-downsampled by ``scale``, at the pixels whose
    3x3 neighbourhood lies wholly inside ``mask (B, 1, H, W)`` (min-pooled like ``scaled_patches``)."""
    if min(images.shape[-2:]) < 3 * scale:  # fewer than 3 pixels a side once downsampled: no gradient
        return images.new_zeros((0, 6))
    if scale > 1:
        images = F.avg_pool2d(images, scale)
        mask = None if mask is None else -F.max_pool2d(-mask, scale)
    channels = torch.einsum("oc,bchw->bohw", images.new_tensor(OPPONENT), images)
    dx = (channels[..., 1:-1, 2:] - channels[..., 1:-1, :-2]) / 2
    dy = (channels[..., 2:, 1:-1] - channels[..., :-2, 1:-1]) / 2
    points = torch.cat([dx, dy], dim=1).permute(0, 2, 3, 1).reshape(-1, 6)
    if mask is None:
        return points
    inside = -F.max_pool2d(-mask, 3, stride=1)  # (B, 1, H-2, W-2): the whole 3x3 neighbourhood inside
    return points[inside.reshape(-1) > 0.5]


def tv_loss(volume: torch.Tensor) -> torch.Tensor:
    """3D total variation (paper Eq. 15): mean squared finite differences along x, y and z.

    ``volume`` is ``(B, C, D, H, W)``. Its gradient is written out (``_TotalVariation``): autograd's, through
    the differences' slices, fills and copies a grid of zeros per slice, 2.4x the time of the whole term
    on a 256^3 look's albedo (and a fifth of that look's fit)."""
    if volume.dim() != 5:
        raise ValueError(f"tv_loss expects (B, C, D, H, W), got {tuple(volume.shape)}.")
    return _TotalVariation.apply(volume)


class _TotalVariation(torch.autograd.Function):
    """``tv_loss``'s value and its gradient: d/dx of mean(diff(x)^2) along an axis of n values is
    2 / count * (diff[i - 1] - diff[i]), the differences missing at the ends taken as zero."""

    @staticmethod
    def forward(ctx, volume):
        ctx.save_for_backward(volume)
        total = volume.new_zeros(())
        for axis in (2, 3, 4):
            if volume.shape[axis] > 1:
                total = total + torch.diff(volume, dim=axis).square_().mean()  # squared in place: one grid fewer
        return total

    @staticmethod
    def backward(ctx, grad_output):
        (volume,) = ctx.saved_tensors
        grad = torch.zeros_like(volume)
        for axis in (2, 3, 4):
            count = volume.shape[axis]
            if count < 2:
                continue
            difference = torch.diff(volume, dim=axis)
            difference.mul_(2.0 * grad_output / difference.numel())
            grad.narrow(axis, 1, count - 1).add_(difference)
            grad.narrow(axis, 0, count - 1).sub_(difference)
        return grad


def temporal_loss(current: torch.Tensor, previous: torch.Tensor, velocity: torch.Tensor) -> torch.Tensor:
    """``mean |V - W(V', U)|^2`` (paper Eq. 16), ``W`` the semi-Lagrangian warp by ``U``.

    ``current`` and ``previous`` are ``(B, C, D, H, W)`` albedo volumes of frames t+1 and t;
    ``velocity (B, 3, D, H, W)`` is frame t's, in voxels per frame, ``(x, y, z)``.
    """
    return ((current - semi_lagrangian_warp(previous, velocity)) ** 2).mean()
