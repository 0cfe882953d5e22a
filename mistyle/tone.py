"""The display transform: linear radiance to the display values that are compared with styles.

One curve serves the losses (on torch tensors, differentiable), the metrics, the PNGs that
mistyle writes and the EXR styles it reads, so "what a render looks like" means one thing.

The module is ``tone``, not ``display``: ``mistyle.display`` is the public function (``api.display``),
and importing a submodule of that name would replace it on the package.
"""

from __future__ import annotations

import numpy as np
import torch

TONE_EPSILON = 1e-3


def tone_map(radiance: torch.Tensor, epsilon: float = TONE_EPSILON) -> torch.Tensor:
    """Smooth, HDR-safe display transform of linear radiance (any shape), differentiable.

    ``y = ((x / (1 + x)) + eps)^(1/2.2) - eps^(1/2.2)``: Reinhard compression keeps any radiance in
    [0, 1), the 2.2 gamma approximates the display encoding of style photographs, and ``eps`` keeps
    the derivative finite at 0 (a plain power has an infinite slope there). Monotone, smooth,
    bounded. (The paper uses Kettunen et al.'s transform for the same purpose.)
    """
    compressed = radiance.clamp_min(0.0) / (1.0 + radiance.clamp_min(0.0))
    return (compressed + epsilon) ** (1.0 / 2.2) - epsilon ** (1.0 / 2.2)


def display(image) -> np.ndarray:
    """Linear radiance ``(..., 3)`` (numpy) -> float32 display values in [0, 1] with ``tone_map``."""
    array = torch.from_numpy(np.ascontiguousarray(image, dtype=np.float32))
    return tone_map(array).clamp(0, 1).numpy()
