"""The style objective on renders, shared by SKPN training and the direct-optimisation baseline.

Renders (linear radiance from the fast layer) are tone-mapped (``mistyle.tone.tone_map``), masked where
they see the medium, passed through the feature extractor, and compared with the style: the
histogram loss (or, for ablations, Gram or mean-std) on every feature level plus the histogram
loss in RGB (paper Sec. 4.4).
"""

from __future__ import annotations

import torch
import torch.nn as nn

from ..conventions import STYLE_LOSSES
from ..tone import tone_map
from .losses import (
    gradient_points,
    gram_loss,
    histogram_loss,
    mean_std_loss,
    scaled_patches,
    sliced_wasserstein_loss,
)
from .masks import pool_mask, render_mask

FEATURE_LOSSES = dict(zip(STYLE_LOSSES, (histogram_loss, gram_loss, mean_std_loss)))


def _shown(images: torch.Tensor, targets: list, masks: torch.Tensor | None):
    """``(B, V, display images (B*V, 3, H, W), masks (B*V, 1, H, W))`` of renders ``(B, V, 3, H, W)``;
    ``masks`` defaults to ``render_mask``."""
    batch, views = images.shape[:2]
    if len(targets) != batch:
        raise ValueError(f"{batch} render batches but {len(targets)} style targets.")
    flat = images.flatten(0, 1)
    shown = tone_map(flat)
    return batch, views, shown, render_mask(flat) if masks is None else masks.to(shown)


class StyleObjective:
    """``loss(images, targets)`` for renders ``(B, V, 3, H, W)`` and per-item style targets.

    Args:
        extractor: feature extractor, images ``(N, 3, H, W)`` in [0, 1] -> four levels.
        style_loss: ``"histogram"``, ``"gram"`` or ``"meanstd"`` for the feature levels.
        rgb_weight: weight of the histogram loss in RGB (always a histogram loss).
    """

    def __init__(self, extractor: nn.Module, style_loss: str = "histogram", rgb_weight: float = 1.0):
        if style_loss not in FEATURE_LOSSES:
            raise ValueError(f"Unknown style loss {style_loss!r}; use one of {', '.join(STYLE_LOSSES)}.")
        self.extractor, self.feature_loss, self.rgb_weight = extractor, FEATURE_LOSSES[style_loss], rgb_weight

    @torch.no_grad()
    def targets(self, styles: torch.Tensor, levels: list[torch.Tensor] | None = None) -> list[list[torch.Tensor]]:
        """Per style ``(3, S, S)`` of ``styles (B, 3, S, S)``: ``[rgb, level1, ..., level4]``, each ``(C, h, w)``.

        ``levels``: the extractor's output for ``styles`` when the caller has it already.
        """
        levels = self.extractor(styles) if levels is None else levels
        return [[styles[item]] + [level[item] for level in levels] for item in range(styles.shape[0])]

    def loss(
        self, images: torch.Tensor, targets: list[list[torch.Tensor]], masks: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Style loss averaged over the batch; ``images (B, V, 3, H, W)`` linear radiance, views of item b
        compared with ``targets[b]``; ``masks (B*V, 1, H, W)``: the pixels to match (default ``render_mask``)."""
        batch, views, display, mask = _shown(images, targets, masks)
        levels = [display] + list(self.extractor(display))
        total = images.new_zeros(())
        for item in range(batch):
            rows = slice(item * views, (item + 1) * views)
            for index, level in enumerate(levels):
                level_mask = pool_mask(mask[rows], level.shape[-2:])
                if index == 0:
                    total = total + self.rgb_weight * histogram_loss(level[rows], targets[item][0], level_mask)
                else:
                    total = total + self.feature_loss(level[rows], targets[item][index], level_mask)
        return total / batch


SLICED_STYLE_SIZE = 128
"""The side of the square style image ``SlicedObjective`` compares with (its 1/4 scale still has 784 patches)."""


class SlicedObjective:
    """Sliced-Wasserstein style objective on display pixels and multi-scale pixel patches.

    ``loss = rgb_weight * SW(pixel colours) + patch_weight * mean over scales SW(5x5 patches) +
    structure_weight * mean over scales SW(gradients)``, each a squared sliced 2-Wasserstein distance
    (``losses.sliced_wasserstein_loss``) between the render's masked values and the style's. The
    gradients are the luminance and colour-opponent channels' ``(d/dx, d/dy)``
    (``losses.gradient_points``) at each of ``structure_scales``, divided by the style's RMS gradient at
    that scale so that every scale counts alike; the style's are taken at ``structure_style_pool`` times
    each scale, for a style shown larger than the renders show the medium. Patches are taken from the
    display image box-downsampled by each of ``patch_scales`` and must lie wholly inside the
    (min-pooled) mask, so the medium's silhouette edge is never compared with the style's interior. The
    same statistics as the benchmark's ``rgb_swd`` and ``patch_swd`` (``metrics.style_fidelity``), in a
    differentiable form.

    ``loss(images, targets, masks)`` takes renders ``(B, V, 3, H, W)`` and optionally masks
    ``(B*V, 1, H, W)`` of the pixels to match (default ``masks.render_mask``).
    """

    def __init__(
        self,
        rgb_weight: float = 1.0,
        patch_weight: float = 1.0,
        patch_size: int = 5,
        patch_scales=(1, 2, 4),
        projections: int = 64,
        max_target_points: int = 8192,
        max_render_patches: int = 4096,
        seed: int = 0,
        structure_weight: float = 0.0,
        structure_scales=(1, 2, 4),
        structure_style_pool: int = 1,
    ):
        self.rgb_weight, self.patch_weight, self.patch_size = rgb_weight, patch_weight, patch_size
        self.patch_scales, self.projections, self.max_target_points = (
            tuple(patch_scales),
            projections,
            max_target_points,
        )
        self.max_render_patches = max_render_patches
        self.structure_weight, self.structure_scales = structure_weight, tuple(structure_scales)
        self.structure_style_pool = int(structure_style_pool)
        self.generator = torch.Generator().manual_seed(seed)

    def _subsample(self, points: torch.Tensor, limit: int | None = None) -> torch.Tensor:
        limit = self.max_target_points if limit is None else limit
        if len(points) <= limit:
            return points
        return points[torch.randperm(len(points), generator=self.generator)[:limit]]

    @torch.no_grad()
    def targets(self, styles: torch.Tensor, levels=None) -> list[list[torch.Tensor]]:
        """Per style of ``styles (B, 3, S, S)``: ``[pixels (N, 3), patches at each scale (N_s, 75)]``, then
        with ``structure_weight`` its scaled gradients at each structure scale ``(N_s, 6)`` and their RMS
        values ``(scales,)`` (``levels``, the extractor's output, is not used: the same call as
        ``StyleObjective``'s)."""
        result = []
        for style in styles:
            entry = [self._subsample(style.reshape(3, -1).T)]
            for scale in self.patch_scales if self.patch_weight else ():
                entry.append(self._subsample(scaled_patches(style[None], None, scale, self.patch_size)))
            rms = []
            for scale in self.structure_scales if self.structure_weight else ():
                gradients = gradient_points(style[None], None, scale * self.structure_style_pool)
                rms.append(gradients.square().mean().sqrt().clamp_min(1e-4))
                entry.append(self._subsample(gradients / rms[-1]))
            if rms:
                entry.append(torch.stack(rms))  # the last item: the style's RMS gradient per structure scale
            result.append(entry)
        return result

    def loss(
        self, images: torch.Tensor, targets: list[list[torch.Tensor]], masks: torch.Tensor | None = None
    ) -> torch.Tensor:
        batch, views, shown, masks = _shown(images, targets, masks)
        total = images.new_zeros(())
        for item in range(batch):
            rows = slice(item * views, (item + 1) * views)
            image, mask = shown[rows], masks[rows]
            pixels = image.permute(0, 2, 3, 1)[mask[:, 0] > 0.5]
            total = total + self.rgb_weight * sliced_wasserstein_loss(
                pixels, targets[item][0], self.projections, self.generator
            )
            if self.patch_weight:
                patch_terms = []
                for scale, target in zip(self.patch_scales, targets[item][1 : 1 + len(self.patch_scales)]):
                    # A fresh random subset each step: over the steps every patch is matched, at a fraction of the cost.
                    patches = self._subsample(
                        scaled_patches(image, mask, scale, self.patch_size), self.max_render_patches
                    )
                    if len(patches):
                        patch_terms.append(sliced_wasserstein_loss(patches, target, self.projections, self.generator))
                if patch_terms:
                    total = total + self.patch_weight * torch.stack(patch_terms).mean()
            if self.structure_weight:
                total = total + self.structure_weight * self._structure_term(image, mask, targets[item])
        return total / batch

    def _structure_term(self, image: torch.Tensor, mask: torch.Tensor, target: list) -> torch.Tensor:
        """The mean over ``structure_scales`` of the SW distance between the render's gradients and the
        style's, both divided by the style's RMS gradient at that scale."""
        gradients = target[-1 - len(self.structure_scales) : -1]
        terms = []
        for scale, theirs, rms in zip(self.structure_scales, gradients, target[-1]):
            ours = self._subsample(gradient_points(image, mask, scale), self.max_render_patches)
            if len(ours):
                terms.append(sliced_wasserstein_loss(ours / rms, theirs, self.projections, self.generator))
        return torch.stack(terms).mean() if terms else image.new_zeros(())


def make_objective(loss_config, extractor: nn.Module):
    """The training objective a ``model.config.LossConfig`` names (``objective``, ``style``, weights)."""
    if loss_config.objective == "sliced":
        return SlicedObjective(rgb_weight=loss_config.rgb_weight, patch_weight=loss_config.patch_weight)
    return StyleObjective(extractor, loss_config.style, loss_config.rgb_weight)
