"""The style objective on renders, shared by SKPN training and the direct-optimisation baseline.

Renders (linear radiance from the fast layer) are tone-mapped (``mistyle.display.tone_map``), masked where
they see the medium, passed through the feature extractor, and compared with the style: the
histogram loss (or, for ablations, Gram or mean-std) on every feature level plus the histogram
loss in RGB (paper Sec. 4.4).
"""

from __future__ import annotations

import torch
import torch.nn as nn

from ..conventions import STYLE_LOSSES
from ..display import tone_map
from .losses import gram_loss, histogram_loss, mean_std_loss
from .masks import pool_mask, render_mask

FEATURE_LOSSES = dict(zip(STYLE_LOSSES, (histogram_loss, gram_loss, mean_std_loss)))


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

    def loss(self, images: torch.Tensor, targets: list[list[torch.Tensor]]) -> torch.Tensor:
        """Style loss averaged over the batch; ``images (B, V, 3, H, W)`` linear radiance, views of item b
        compared with ``targets[b]``."""
        batch, views = images.shape[:2]
        if len(targets) != batch:
            raise ValueError(f"{batch} render batches but {len(targets)} style targets.")
        flat = images.flatten(0, 1)
        display = tone_map(flat)
        mask = render_mask(flat)
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
