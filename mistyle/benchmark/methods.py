"""The benchmark's methods, registered by name: the product, its baselines and its upper reference.

Each method maps ``(context, density (Z, Y, X), style (H, W, 3))`` to an albedo ``(Z, Y, X, 3)`` in
[0, 1]; the runner path traces and scores every albedo the same way.

The two **training-free baselines** exist to keep the colour match honest: they involve no network,
and are given the style's colours by the same ``Stylizer.match_colours`` the product applies after
the network. A post-processing stage that lifts them as much as the network proves nothing about the
network.

* ``density_ramp``: the density's rank among the occupied voxels, as a grey albedo.
* ``smooth_noise``: independent Gaussian noise per channel, blurred by ``NOISE_SIGMA`` of the grid's
  longest side (3 voxels at 64^3) and stretched to [0, 1] per channel.
* ``tuned_noise``: the same kind of field made as the network's noise site makes its fields (filtered
  in the frequency domain, so it wraps around the box: no edge is flatter than the middle) at
  ``TUNED_NOISE_SIGMA``, the scale that came closest to the validation paintings
  (``experiments/noise_field_probe.py``, ``results/noise_fields/``). The strongest training-free field
  mistyle knows of: what a network adds beyond noise of the right scale shows against it.
* ``solid_texture``: a solid texture synthesised from the style (``mistyle.solid_texture``: its slices
  have the style's multi-scale patches) laid over the density's box. Where the noises have one scale
  and no orientation, it carries the style's own strokes: a look that claims structure must beat it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

NOISE_SIGMA = 3 / 64
"""The smooth noise's blur, as a fraction of the grid's longest side: structures of one size in the box."""
TUNED_NOISE_SIGMA = 6 / 64
"""``tuned_noise``'s scale (fraction of the longest side), chosen on the validation split only."""
QUICK_STEPS = (4, 1)
"""Refinement and optimisation steps (fast layer, path traced) in quick mode."""


@dataclass
class Context:
    """What every method of one run shares: the loaded network and the metric views."""

    stylizer: object  # pipeline.Stylizer
    views: list  # scenes.View: the metric views (the uniform baseline is matched on the first two)
    quick: bool = False
    optimise_factor: float = 2.0  # direct optimisation runs this many times the default refinement's steps
    seed: int = 0
    _pipelines: dict = field(default_factory=dict, repr=False)

    @property
    def density_scale(self) -> float:
        return self.stylizer.density_scale

    @property
    def radiance(self) -> float:
        return self.stylizer.config.render.radiance

    def pipeline(self, **settings):
        """A ``pipeline.Pipeline`` on the shared network with these ``PipelineSettings`` fields."""
        from ..pipeline import Pipeline, PipelineSettings

        key = tuple(sorted(settings.items()))
        if key not in self._pipelines:
            self._pipelines[key] = Pipeline(
                PipelineSettings(checkpoint=self.stylizer.path, **settings), stylizer=self.stylizer
            )
        return self._pipelines[key]


@dataclass(frozen=True)
class Method:
    name: str
    role: str  # "product" | "ablation" | "baseline" | "reference"
    description: str
    albedo: Callable  # (Context, density, style) -> (Z, Y, X, 3)
    uses_network: bool = False


def uniform_albedo(context: Context, density: np.ndarray, style: np.ndarray) -> np.ndarray:
    """One colour whose path-traced foreground has the style's mean display colour (matched on the
    first two metric views)."""
    return uniform_baseline(
        density, style, context.views, density_scale=context.density_scale, radiance=context.radiance
    )


def uniform_baseline(density, style, views, *, density_scale: float, radiance: float) -> np.ndarray:
    """The must-beat baseline's albedo ``(Z, Y, X, 3)``: one colour matched to the style's mean on the
    first two of ``views`` (``uniform_albedo``'s, for a density scale and light given directly)."""
    from ..response import matched_uniform_albedo

    colour = matched_uniform_albedo(density, density_scale, radiance, style, views[:2], res=64, spp=16)
    return np.ascontiguousarray(np.broadcast_to(colour, density.shape + (3,)), dtype=np.float32)


def density_ramp(density: np.ndarray) -> np.ndarray:
    """Grey albedo ``(Z, Y, X, 3)``: each occupied voxel's rank in density, in (0, 1]; empty voxels 0."""
    ramp = np.zeros(density.size, np.float32)
    occupied = np.flatnonzero(density.ravel() > 0)
    order = occupied[np.argsort(density.ravel()[occupied], kind="stable")]
    ramp[order] = np.arange(1, len(order) + 1, dtype=np.float32) / max(len(order), 1)
    return np.repeat(ramp.reshape(density.shape)[..., None], 3, axis=-1)


def smooth_noise(shape: tuple, seed: int = 0, sigma: float = NOISE_SIGMA) -> np.ndarray:
    """RGB noise ``shape + (3,)`` in [0, 1]: Gaussian per channel, blurred by ``sigma`` times the longest
    side (a separable Gaussian, zero padded), each channel stretched to span [0, 1]."""
    import torch
    import torch.nn.functional as F

    voxels = max(sigma * max(shape), 1e-3)
    radius = max(1, int(np.ceil(3 * voxels)))
    taps = torch.exp(-0.5 * (torch.arange(-radius, radius + 1, dtype=torch.float64) / voxels) ** 2)
    taps = (taps / taps.sum()).to(torch.float32)
    generator = torch.Generator().manual_seed(seed)
    field = torch.randn((3, 1) + tuple(shape), generator=generator)
    for axis in range(3):
        kernel = taps.view((1, 1) + tuple(len(taps) if a == axis else 1 for a in range(3)))
        padding = tuple(radius if a == axis else 0 for a in range(3))
        field = F.conv3d(field, kernel, padding=padding)
    field = field[:, 0].permute(1, 2, 3, 0).numpy()
    low, high = field.reshape(-1, 3).min(axis=0), field.reshape(-1, 3).max(axis=0)
    return np.ascontiguousarray((field - low) / np.maximum(high - low, 1e-12), dtype=np.float32)


def tuned_noise(shape: tuple, seed: int = 0, sigma: float = TUNED_NOISE_SIGMA) -> np.ndarray:
    """RGB noise ``shape + (3,)`` in [0, 1]: three of ``model.noise``'s wrapped fields at ``sigma`` of the
    longest side, each channel stretched to span [0, 1]."""
    from ..model.noise import noise_fields

    field = noise_fields(tuple(shape), (sigma,), 3, seed).permute(1, 2, 3, 0).numpy()
    low, high = field.reshape(-1, 3).min(axis=0), field.reshape(-1, 3).max(axis=0)
    return np.ascontiguousarray((field - low) / np.maximum(high - low, 1e-12), dtype=np.float32)


QUICK_SOLID_TEXTURE = dict(side=32, levels=2, steps=8)
"""The solid texture's settings in quick mode: a small cube, a few steps."""


def colour_matched(context: Context, field: np.ndarray, density: np.ndarray, style: np.ndarray) -> np.ndarray:
    """``field`` given the style's colours by the product's colour match."""
    return context.stylizer.match_colours([field], [density], style)[0]


def _density_ramp(context, density, style):
    return colour_matched(context, density_ramp(density), density, style)


def _smooth_noise(context, density, style):
    return colour_matched(context, smooth_noise(density.shape, context.seed), density, style)


def _tuned_noise(context, density, style):
    return colour_matched(context, tuned_noise(density.shape, context.seed), density, style)


def _solid_texture(context, density, style):
    from ..solid_texture import SolidTextureSettings, lay_over, solid_texture_of

    quick = QUICK_SOLID_TEXTURE if context.quick else {}
    texture = solid_texture_of(style, SolidTextureSettings(seed=context.seed, **quick))
    return colour_matched(context, lay_over(texture, density), density, style)


def _network(context, density, style):
    return context.pipeline(refine_steps=0, refine_path_steps=0).stylize(density, style).albedos[0]


def _network_unmatched(context, density, style):
    return context.pipeline(refine_steps=0, refine_path_steps=0, colour_match=False).stylize(density, style).albedos[0]


def _default(context, density, style):
    steps = {"look_steps": QUICK_STEPS[0]} if context.quick else {}
    return context.pipeline(**steps).stylize(density, style).albedos[0]


def _refined(context, density, style):
    from ..pipeline import default_refinement

    schedule = default_refinement(context.stylizer.config)
    steps = QUICK_STEPS if context.quick else (schedule.layer_steps, schedule.path_steps)
    return context.pipeline(refine_steps=steps[0], refine_path_steps=steps[1]).stylize(density, style).albedos[0]


def _look(context, density, style):
    from ..look import LookSettings

    settings = LookSettings(steps=QUICK_STEPS[0]) if context.quick else None
    pipeline = context.pipeline(refine_steps=0, refine_path_steps=0)
    return pipeline.fit_look(density, style, look_settings=settings).stylize(density)


def _optimised(context, density, style):
    from dataclasses import replace

    from ..fit import refine_albedo
    from ..pipeline import default_refinement

    schedule = default_refinement(context.stylizer.config)
    if context.quick:
        schedule = replace(schedule, layer_steps=QUICK_STEPS[0], path_steps=QUICK_STEPS[1])
    else:
        schedule = schedule.scaled(context.optimise_factor)
    albedo, _ = refine_albedo(
        density,
        context.density_scale,
        uniform_albedo(context, density, style),
        style,
        schedule,
        radiance=context.radiance,
    )
    return albedo


METHODS = {
    method.name: method
    for method in (
        Method(
            "default",
            "product",
            "mistyle-render's default output (a look fitted on the frame, Pipeline.fits_look)",
            _default,
            uses_network=True,
        ),
        Method(
            "refined",
            "product",
            "network, colour match, then default_refinement's 120 layer + 16 path-traced steps (the default until #32)",
            _refined,
            uses_network=True,
        ),
        Method(
            "network",
            "product",
            "feed-forward (--refine 0): the network, then the colour match",
            _network,
            uses_network=True,
        ),
        Method(
            "look",
            "product",
            "a look fitted on the pair's density (mistyle-render --save-look), applied without refinement",
            _look,
            uses_network=True,
        ),
        Method(
            "network_unmatched",
            "ablation",
            "the network's albedo as predicted (--no-colour-match)",
            _network_unmatched,
            uses_network=True,
        ),
        Method(
            "density_ramp",
            "baseline",
            "training-free: the density's rank as grey, then the colour match",
            _density_ramp,
        ),
        Method("smooth_noise", "baseline", "training-free: smooth RGB noise, then the colour match", _smooth_noise),
        Method(
            "tuned_noise",
            "baseline",
            "training-free: wrapped RGB noise at the scale best on validation, then the colour match",
            _tuned_noise,
        ),
        Method(
            "solid_texture",
            "baseline",
            "training-free: a solid texture synthesised from the style laid over the box, then the colour match",
            _solid_texture,
        ),
        Method(
            "uniform", "baseline", "one colour matched to the style's mean (the must-beat baseline)", uniform_albedo
        ),
        Method(
            "optimised", "reference", "direct optimisation of the albedo grid from the uniform baseline", _optimised
        ),
    )
}


def timed(method: Method, context: Context, density: np.ndarray, style: np.ndarray) -> tuple[np.ndarray, float]:
    """``method``'s albedo and the seconds it took."""
    started = time.perf_counter()
    albedo = method.albedo(context, density, style)
    return albedo, time.perf_counter() - started
