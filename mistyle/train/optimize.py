"""Direct per-volume optimisation of an albedo grid against a style, through the fast layer.

The "tomography-like" baseline of the paper's comparisons: no network, the albedo grid itself
(``sigmoid`` of free logits) is fitted with the same style objective, views and TV weight as SKPN
training. ``python -m mistyle.train --optimize`` runs it against the trained network.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch

from ..scenes import CameraPath, PreparedDensity
from ..scenes.builder import DEFAULT_ENV_RADIANCE
from .losses import tv_loss
from .objective import StyleObjective


@dataclass
class DirectFit:
    albedo: torch.Tensor  # (3, Z, Y, X) in [0, 1]
    seconds: float
    losses: list[float]


def optimize_albedo(
    prepared: PreparedDensity,
    style: torch.Tensor,
    objective: StyleObjective,
    steps: int = 300,
    lr: float = 0.05,
    image_size: int = 96,
    views: int = 4,
    render_steps: int = 64,
    radiance: float = DEFAULT_ENV_RADIANCE,
    tv_weight: float = 10.0,
    seed: int = 0,
    camera_distance: float = 2.5,
    initial: torch.Tensor | None = None,
) -> DirectFit:
    """Fit ``albedo (3, Z, Y, X)`` to ``style (3, S, S)`` with ``steps`` Adam updates on random orbit views.

    ``initial`` (``(3, Z, Y, X)`` in (0, 1)) starts from a given albedo (e.g. a network's) instead of 0.5.
    """
    from ..bridge_torch import render_views

    if initial is None:
        logits = torch.zeros((3,) + prepared.shape)
    else:
        logits = torch.logit(initial.detach().clamp(1e-3, 1 - 1e-3))
    logits.requires_grad_(True)
    optimizer = torch.optim.Adam([logits], lr=lr)
    targets = objective.targets(style[None])
    path, rng = CameraPath(distance=camera_distance), np.random.default_rng(seed)
    losses = []
    started = time.perf_counter()
    for _ in range(steps):
        albedo = torch.sigmoid(logits)
        images = render_views(albedo, prepared, path.sample(views, rng), image_size, steps=render_steps, radiance=radiance)
        loss = objective.loss(images[None], targets) + tv_weight * tv_loss(albedo[None])
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        losses.append(float(loss.detach()))
    return DirectFit(torch.sigmoid(logits).detach(), time.perf_counter() - started, losses)
