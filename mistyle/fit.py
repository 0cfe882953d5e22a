"""The one albedo-fitting loop: Adam on an albedo grid against a style, through a differentiable renderer.

Used by the direct-optimisation baseline (the paper's "tomography-like" comparison: no network,
the grid itself is fitted through the fast layer with the training objective) and by the final
render's refinement (the same loop with the path tracer, ``bridge_torch.PathTracedViews``, so the
albedo is fitted to what the final image shows, multiple scattering included).

The albedo is ``sigmoid`` of free logits, so it stays in [0, 1]. Each step renders
``views_per_step`` random views on the training orbit and minimises
``objective.loss(views) + tv_weight * TV(albedo)``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import torch

from .conventions import DEFAULT_ENV_RADIANCE, ORBIT_DISTANCE
from .objective.losses import tv_loss
from .objective.style import StyleObjective
from .scenes import CameraPath, View

Renderer = Callable[[torch.Tensor, Sequence[View], int], torch.Tensor]
"""``render(albedo (3, Z, Y, X), views, seed) -> (V, 3, H, W)`` linear radiance, differentiable."""


@dataclass
class FitSettings:
    steps: int = 300
    lr: float = 0.05
    views_per_step: int = 4
    tv_weight: float = 10.0
    camera_distance: float = ORBIT_DISTANCE
    seed: int = 0


@dataclass
class AlbedoFit:
    albedo: torch.Tensor  # (3, Z, Y, X) in [0, 1]
    seconds: float
    losses: list[float] = field(default_factory=list)


def fit_albedo(render: Renderer, style: torch.Tensor, objective: StyleObjective, initial: torch.Tensor,
               settings: FitSettings = FitSettings(), progress=None) -> AlbedoFit:
    """Fit an albedo grid to ``style (3, S, S)`` starting from ``initial (3, Z, Y, X)`` in [0, 1].

    ``progress(step, steps, loss)`` is called after every step when given.
    """
    logits = torch.logit(initial.detach().to(torch.float32).clamp(1e-3, 1 - 1e-3)).requires_grad_(True)
    optimizer = torch.optim.Adam([logits], lr=settings.lr)
    targets = objective.targets(style[None])
    orbit, rng = CameraPath(distance=settings.camera_distance), np.random.default_rng(settings.seed)
    losses = []
    started = time.perf_counter()
    for step in range(settings.steps):
        albedo = torch.sigmoid(logits)
        images = render(albedo, orbit.sample(settings.views_per_step, rng), step * settings.views_per_step)
        loss = objective.loss(images[None], targets) + settings.tv_weight * tv_loss(albedo[None])
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        losses.append(float(loss.detach()))
        if progress is not None:
            progress(step + 1, settings.steps, losses[-1])
    return AlbedoFit(torch.sigmoid(logits).detach(), time.perf_counter() - started, losses)


def refine_albedo(density: np.ndarray, density_scale: float, albedo: np.ndarray, style: torch.Tensor,
                  objective: StyleObjective, settings: FitSettings, *, res: int = 64, spp: int = 8,
                  radiance: float = DEFAULT_ENV_RADIANCE, device: str = "cpu", progress=None) -> tuple[np.ndarray, float]:
    """``fit_albedo`` with the path tracer in the loop (``prbvolpath``, multiple scattering).

    Starts from ``albedo (Z, Y, X, 3)``; returns ``(refined albedo (Z, Y, X, 3), seconds)``. Each step
    renders ``settings.views_per_step`` views at ``res``^2 with ``spp`` paths per pixel.
    """
    from .bridge_torch import PathTracedViews

    render = PathTracedViews(density, density_scale, res=res, spp=spp, radiance=radiance, device=device)
    initial = torch.from_numpy(np.ascontiguousarray(albedo, dtype=np.float32)).permute(3, 0, 1, 2)
    fit = fit_albedo(render, style, objective, initial, settings, progress=progress)
    return np.ascontiguousarray(fit.albedo.permute(1, 2, 3, 0).numpy()), fit.seconds
