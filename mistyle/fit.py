"""The one albedo-fitting loop (``fit_steps``), and Adam on an albedo grid against a style through a
differentiable renderer (``fit_albedo``).

``fit_steps`` is every fit's loop: per step a stop if one was asked for, the step's loss (views, render,
objective with its mask, smoothness: what the caller's ``step_loss`` computes of its parametrisation),
its gradient, Adam's step, a projection, progress; and, where asked, the guard against a fit that
diverges (``diverged``). A look's fit (``mistyle.look``: the network's head and a texture) and the
albedo grid's fits here are its two parametrisations.

Used by the direct-optimisation reference (the paper's "tomography-like" comparison: no network,
the grid itself is fitted), by the final render's refinement and by the objective study. The
renderer is the fast layer (``LayerViews``) or the path tracer (``bridge_torch.PathTracedViews``,
multiple scattering, so the albedo is fitted to what the final image shows).

Parametrisation (``FitSettings.parametrisation``):

* ``"log"`` (default): albedo = exp(y), y <= 0 (projected after each step). Equal steps in y are
  equal *ratios* of albedo, so the dark, saturated corner of albedo space where most of a
  render's visible range lives (albedo 0.003-0.3 spans display 0.07-0.64 on a smoke plume) is as
  reachable as the bright one.
* ``"sigmoid"``: albedo = sigmoid(x), the earlier choice; steps near 0.5 are small in ratio, and
  dark colours are rarely reached.

Each step renders ``views_per_step`` random views on the training orbit and minimises
``objective.loss(views, targets, masks) + tv_weight * TV(albedo)``; ``masks(views)`` (optional)
gives the pixels each view's style term sees (e.g. ``LayerViews.body_masks``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import torch

from .adam import Adam
from .conventions import (
    DEFAULT_ENV_RADIANCE,
    LAYER_MARCH_STEPS,
    ORBIT_DISTANCE,
    REFINE_LAYER_STEPS,
    REFINE_PATH_STEPS,
)
from .objective.losses import tv_loss
from .objective.masks import body_mask
from .scenes import CameraPath, View
from .stops import raise_if_requested

Renderer = Callable[[torch.Tensor, Sequence[View], int], torch.Tensor]
"""``render(albedo (3, Z, Y, X), views, seed) -> (V, 3, H, W)`` linear radiance, differentiable."""
MaskMaker = Callable[[Sequence[View]], torch.Tensor]
"""``masks(views) -> (V, 1, H, W)`` in {0, 1}: the pixels of each view the style term compares."""

PARAMETRISATIONS = ("log", "sigmoid")
MIN_ALBEDO = 1e-4  # the log parametrisation's floor: display 0.02 under the training light


DIVERGENCE_WINDOW = 10
"""Steps whose mean loss a fit's start and end are compared by (``diverged``)."""


def diverged(losses: Sequence[float]) -> bool:
    """Whether a fit's ``losses`` (one a step) end higher than they started: the mean of the last
    ``DIVERGENCE_WINDOW`` steps (of the last half, for a short fit) above the first step's, the loss
    of the start. A fit that converges ends below its start (0.09-0.99 of it on 56 of the benchmark's
    63 pairs, ``results/look_divergence/``); one that diverged, as a look's gradient term did on
    a few styles of fine, high-contrast texture by pinning the head's colours at its bounds within a
    few steps (a flat colour whose only gradients are the silhouette's), ends above it. Each step's
    loss is measured on other random views, so the end is a mean over steps."""
    window = min(DIVERGENCE_WINDOW, len(losses) // 2)
    return window > 0 and float(np.mean(losses[-window:])) > losses[0]


@dataclass
class FittedSteps:
    """What ``fit_steps`` did: each step's loss, and where a diverging fit went back to, if it did."""

    losses: list[float]
    kept_step: int | None = None  # 1-based step whose values a diverged fit kept (``keep_lowest``), or None


def fit_steps(
    step_loss: Callable[[int], torch.Tensor],
    optimizer: Adam,
    steps: int,
    progress=None,
    project: Callable[[], None] | None = None,
    keep_lowest: bool = False,
) -> FittedSteps:
    """``steps`` Adam steps of ``optimizer`` on ``step_loss(step)`` (differentiable in its parameters),
    each followed by ``project()`` when given and ``progress(step, steps, loss)``. ``keep_lowest``: if
    the fit ``diverged``, its parameters go back to the values of its lowest loss (as they were when that
    loss was computed)."""
    parameters = [parameter for group in optimizer.groups for parameter in group["params"]]
    losses, best_loss, best_values = [], math.inf, None
    for step in range(steps):
        raise_if_requested()
        loss = step_loss(step)
        optimizer.zero_grad()
        loss.backward()
        losses.append(float(loss.detach()))
        if keep_lowest and losses[-1] < best_loss:  # the values this step's loss was computed with
            best_loss, best_values = losses[-1], [parameter.detach().clone() for parameter in parameters]
        optimizer.step()
        if project is not None:
            project()
        if progress is not None:
            progress(step + 1, steps, losses[-1])
    if not (keep_lowest and diverged(losses)):
        return FittedSteps(losses)
    with torch.no_grad():
        for parameter, value in zip(parameters, best_values):
            parameter.copy_(value)
    return FittedSteps(losses, losses.index(best_loss) + 1)


@dataclass
class FitSettings:
    steps: int = 300
    lr: float = 0.05
    views_per_step: int = 4
    tv_weight: float = 10.0
    camera_distance: float = ORBIT_DISTANCE
    parametrisation: str = "log"
    seed: int = 0

    def __post_init__(self):
        if self.parametrisation not in PARAMETRISATIONS:
            raise ValueError(
                f"Unknown parametrisation {self.parametrisation!r}; use one of {', '.join(PARAMETRISATIONS)}."
            )


@dataclass
class AlbedoFit:
    albedo: torch.Tensor  # (3, Z, Y, X) in [0, 1]
    seconds: float
    losses: list[float] = field(default_factory=list)


class _Albedo:
    """The free variable of a fit and its map to albedo (see the module docstring)."""

    def __init__(self, initial: torch.Tensor, parametrisation: str):
        self.log = parametrisation == "log"
        initial = initial.detach().to(torch.float32)
        if self.log:
            self.free = initial.clamp(MIN_ALBEDO, 1.0).log().requires_grad_(True)
        else:
            self.free = torch.logit(initial.clamp(1e-3, 1 - 1e-3)).requires_grad_(True)

    def albedo(self) -> torch.Tensor:
        return self.free.exp() if self.log else torch.sigmoid(self.free)

    @torch.no_grad()
    def project(self) -> None:
        if self.log:
            self.free.clamp_(math.log(MIN_ALBEDO), 0.0)


def fit_albedo(
    render: Renderer,
    style: torch.Tensor,
    objective,
    initial: torch.Tensor,
    settings: FitSettings | None = None,
    progress=None,
    masks: MaskMaker | None = None,
    penalty: Callable[[torch.Tensor], torch.Tensor] | None = None,
) -> AlbedoFit:
    """Fit an albedo grid to ``style (3, S, S)`` starting from ``initial (3, Z, Y, X)`` in [0, 1].

    ``objective``: ``objective.style.StyleObjective`` or ``SlicedObjective``. ``penalty(albedo)``, when
    given, is added to every step's loss (e.g. the temporal term of a sequence). ``progress(step,
    steps, loss)`` is called after every step when given.
    """
    settings = FitSettings() if settings is None else settings
    variable = _Albedo(initial, settings.parametrisation)
    optimizer = Adam([variable.free], lr=settings.lr)
    targets = objective.targets(style[None])
    orbit, rng = CameraPath(distance=settings.camera_distance), np.random.default_rng(settings.seed)
    started = time.perf_counter()

    def step_loss(step: int) -> torch.Tensor:
        albedo = variable.albedo()
        views = orbit.sample(settings.views_per_step, rng)
        images = render(albedo, views, step * settings.views_per_step)
        loss = objective.loss(
            images[None], targets, None if masks is None else masks(views)
        ) + settings.tv_weight * tv_loss(albedo[None])
        return loss if penalty is None else loss + penalty(albedo)

    fitted = fit_steps(step_loss, optimizer, settings.steps, progress, project=variable.project)
    return AlbedoFit(variable.albedo().detach(), time.perf_counter() - started, fitted.losses)


class LayerViews:
    """The fast layer as a ``Renderer`` for one prepared density, and its body masks.

    ``views(albedo (3, Z, Y, X), views, seed) -> (V, 3, res, res)``; ``body_masks(views)`` keeps the
    medium's body (``objective.masks.body_mask``) in the views of a white albedo (no gradient), for this
    renderer or any other with the same cameras. A render's march also gives its views' white images
    (``render_views``' ``white``), so the masks of the views just rendered cost no second render.
    """

    def __init__(
        self,
        prepared,
        res: int,
        steps: int = LAYER_MARCH_STEPS,
        radiance: float = DEFAULT_ENV_RADIANCE,
        device: str = "cpu",
    ):
        self.prepared, self.res, self.steps, self.radiance = prepared, int(res), int(steps), float(radiance)
        self.device = device
        self._last_white: tuple[list[View], torch.Tensor] | None = None  # the views last rendered, their white images

    def __call__(self, albedo: torch.Tensor, views: Sequence[View], seed: int = 0) -> torch.Tensor:
        from .bridge_torch import render_views

        views = list(views)
        images, white = render_views(
            albedo, self.prepared, views, self.res, steps=self.steps, radiance=self.radiance, white=True
        )
        self._last_white = (views, white)
        return images

    def body_masks(self, views: Sequence[View], res: int | None = None) -> torch.Tensor:
        from .bridge_torch import render_views

        views = list(views)
        if self._last_white is not None and (res or self.res) == self.res and self._last_white[0] == views:
            return body_mask(self._last_white[1])
        white = torch.ones((3,) + tuple(self.prepared.density.shape), dtype=torch.float32, device=self.device)
        with torch.no_grad():
            images = render_views(
                white, self.prepared, views, res or self.res, steps=self.steps, radiance=self.radiance
            )
        return body_mask(images)


@dataclass
class RefineSettings:
    """A refinement schedule: ``layer_steps`` through the fast layer (single scattering, cheap), then
    ``path_steps`` with the path tracer in the loop (multiple scattering, what the final image shows).

    The objective is ``objective.style.SlicedObjective`` (RGB and patch sliced Wasserstein, weights
    ``rgb_weight`` and ``patch_weight``) on the medium's body (``LayerViews.body_masks``), with the
    log-albedo parametrisation. These defaults are ``render_final``'s, chosen by
    ``experiments/objective_study.py`` (``docs/decisions/2026-11-25-style-fidelity-study.md``): the layer
    steps find the style's hues and patterns, the path-traced steps then absorb what multiple scattering changes.
    """

    layer_steps: int = REFINE_LAYER_STEPS
    path_steps: int = REFINE_PATH_STEPS
    layer_res: int = 64
    path_res: int = 64
    spp: int = 8
    views_per_step: int = 4
    path_views_per_step: int = 2
    lr: float = 0.05
    tv_weight: float = 10.0
    rgb_weight: float = 1.0
    patch_weight: float = 0.05
    camera_distance: float = ORBIT_DISTANCE
    layer_steps_per_ray: int = LAYER_MARCH_STEPS
    # Sequences: the least flicker of 10 / 100 / 1000 (docs/decisions/2026-11-25-style-fidelity-study.md).
    temporal_weight: float = 100.0
    seed: int = 0

    def scaled(self, factor: float) -> RefineSettings:
        """The same schedule with ``factor`` times the steps."""
        from dataclasses import replace

        return replace(self, layer_steps=round(self.layer_steps * factor), path_steps=round(self.path_steps * factor))

    def fit_settings(self, steps: int, views: int) -> FitSettings:
        return FitSettings(
            steps=steps,
            lr=self.lr,
            views_per_step=views,
            tv_weight=self.tv_weight,
            camera_distance=self.camera_distance,
            parametrisation="log",
            seed=self.seed,
        )


def refine_albedo(
    density: np.ndarray,
    density_scale: float,
    albedo: np.ndarray,
    style: np.ndarray,
    settings: RefineSettings,
    *,
    radiance: float = DEFAULT_ENV_RADIANCE,
    device: str = "cpu",
    prepared=None,
    anchor: np.ndarray | None = None,
    progress=None,
) -> tuple[np.ndarray, float]:
    """Refine ``albedo (Z, Y, X, 3)`` towards the display-space ``style (H, W, 3)``: returns
    ``(refined albedo (Z, Y, X, 3), seconds)``.

    ``prepared``: the density's ``PreparedDensity`` when the caller has it. ``anchor (Z, Y, X, 3)``: for a
    sequence, the previous frame's refined albedo warped to this frame; ``settings.temporal_weight *
    mean |albedo - anchor|^2`` (the paper's temporal loss, Eq. 16) keeps consecutive frames coherent.
    ``progress(stage, step, steps, loss)`` is called after every step when given, ``stage`` being
    ``"layer"`` or ``"path"``.
    """
    from .bridge_torch import PathTracedViews
    from .integrators import prepare_density
    from .model.features import square_style
    from .objective.style import SLICED_STYLE_SIZE, SlicedObjective

    started = time.perf_counter()
    prepared = prepare_density(density, density_scale) if prepared is None else prepared
    target = square_style(style, SLICED_STYLE_SIZE).to(device)
    objective = SlicedObjective(rgb_weight=settings.rgb_weight, patch_weight=settings.patch_weight, seed=settings.seed)
    current = torch.from_numpy(np.ascontiguousarray(albedo, dtype=np.float32)).permute(3, 0, 1, 2).to(device)

    def reporter(stage):
        return None if progress is None else (lambda step, steps, loss: progress(stage, step, steps, loss))

    penalty = None
    if anchor is not None:
        target_albedo = torch.from_numpy(np.ascontiguousarray(anchor, dtype=np.float32)).permute(3, 0, 1, 2).to(device)
        penalty = lambda grid: settings.temporal_weight * ((grid - target_albedo) ** 2).mean()  # noqa: E731

    if settings.layer_steps:
        layer = LayerViews(
            prepared, settings.layer_res, steps=settings.layer_steps_per_ray, radiance=radiance, device=device
        )
        current = fit_albedo(
            layer,
            target,
            objective,
            current,
            settings.fit_settings(settings.layer_steps, settings.views_per_step),
            progress=reporter("layer"),
            masks=layer.body_masks,
            penalty=penalty,
        ).albedo
    if settings.path_steps:
        masks = LayerViews(
            prepared, settings.path_res, steps=settings.layer_steps_per_ray, radiance=radiance, device=device
        ).body_masks
        render = PathTracedViews(
            density, density_scale, res=settings.path_res, spp=settings.spp, radiance=radiance, device=device
        )
        current = fit_albedo(
            render,
            target,
            objective,
            current,
            settings.fit_settings(settings.path_steps, settings.path_views_per_step),
            progress=reporter("path"),
            masks=masks,
            penalty=penalty,
        ).albedo
    return np.ascontiguousarray(current.permute(1, 2, 3, 0).cpu().numpy()), time.perf_counter() - started
