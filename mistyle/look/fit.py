"""Fitting a look: the tuned parts, the fit's steps through the fast layer, the colour match after."""

from __future__ import annotations

import copy
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from .fitted import Look, checkpoint_digest
from .frames import (
    cropped_fit,
    frame_albedo,
    frame_key,
    prepare_frame,
    solid_texture_start,
    thumbnail_of,
)
from .settings import LookSettings, default_key_frames


def fit_look(
    stylizer,
    densities: Sequence[np.ndarray],
    style,
    *,
    key_frames: Sequence[int] | None = None,
    density_scale: float | None = None,
    camera_distance: float | None = None,
    scale_structures: float = 1.0,
    settings: LookSettings | None = None,
    notes: list | None = None,
    progress: Callable[[int, int, float], None] | None = None,
    style_names: list[str] | None = None,
    prepared: Callable[[int], object] | None = None,
) -> Look:
    """Fit a ``Look`` of ``style`` (an image or path, a mix ``[(style, weight)]`` or a ``style.Style``) on the
    ``key_frames`` (default ``default_key_frames``) of ``densities`` (checked ``(Z, Y, X)`` frames of one
    shape) with ``stylizer``'s network (``stylizer.Stylizer``). ``progress(step, steps, loss)`` after
    each step. ``style_names``: what the look calls its style (default: the image files' names).
    ``prepared(index)``: frame ``index`` prepared for the fast layer at ``density_scale``, when the
    caller keeps them (``pipeline.Frames.prepared``); else each key frame is prepared here."""

    from ..integrators import prepare_density
    from ..model.skpn import StylizingKernels
    from ..stops import raise_if_requested
    from ..style import Style

    settings = LookSettings() if settings is None else settings
    started = time.perf_counter()
    densities = [np.asarray(d, dtype=np.float32) for d in densities]
    keys = _key_frames(densities, key_frames)
    density_scale = stylizer.density_scale if density_scale is None else float(density_scale)
    config = stylizer.config
    camera_distance = config.render.camera_distance if camera_distance is None else float(camera_distance)
    scene = _FitScene(density_scale, camera_distance, config.render.radiance)
    style = Style.of(style, notes, style_names)
    target = style.target
    fit = _tuned_parameters(stylizer, style, target, densities[keys[0]].shape, settings)

    # Per key frame, what does not change during the fit: the encoder's features (and the decoder as far
    # as nothing in it is tuned, LookSettings.fixed_stage), the crop and the layer's Ls grid.
    fixed_kernels = StylizingKernels(fit.free) if settings.fixed_stage is not None else None
    frames = []
    for key in keys:
        raise_if_requested()
        frames.append(prepare_frame(fit.network, densities[key], scale_structures, fixed_kernels, settings.fixed_stage))
    prepared_densities = []
    for key in keys:
        raise_if_requested()
        prepared_densities.append(prepare_density(densities[key], density_scale) if prepared is None else prepared(key))

    losses = _fit_steps(fit, frames, prepared_densities, target, scene, settings, notes, progress)

    kernels = StylizingKernels(
        {site: {key: value.detach() for key, value in kernel.items()} for site, kernel in fit.free.items()}
    )
    decoder = {
        f"{index}.{name}": value.detach().clone()
        for index in settings.tune_decoder
        for name, value in fit.network.decoder[index].named_parameters()
    }
    meta = {
        "checkpoint_sha256": checkpoint_digest(stylizer.path),
        "checkpoint_name": stylizer.path.name,
        "style": style.describe(),
        "density_scale": density_scale,
        "camera_distance": camera_distance,
        "scale_structures": float(scale_structures),
        "key_frames": keys,
        "key_frame_shape": list(densities[keys[0]].shape),
        "frames_seen": len(densities),
        "settings": {
            key: list(value) if isinstance(value, tuple) else value for key, value in asdict(settings).items()
        },
        "final_loss": losses[-1] if losses else None,
    }
    texture = None if fit.texture is None else fit.texture.detach().half().float()  # as the file keeps it
    look = Look(kernels, decoder, None, thumbnail_of(target), meta, texture, stylizer=stylizer)
    if settings.fixed_stage is not None:
        # What the fit computed once per key frame (encoder features, the decoder up to its fixed stage)
        # is what applying the look computes first, as nothing tuned enters it: kept, applying the look to
        # a key frame (a single frame's default output) computes only the rest, by the plain path.
        for key, frame in zip(keys, frames):
            look._prepared_frames[frame_key(densities[key])] = {**frame, "folded": None}
    # The colour match is fitted after the steps, on the tuned network's albedo: fitted first and through
    # the steps, or left out, it scored worse (docs/decisions/2026-12-02-looks.md).
    raise_if_requested()
    look.colour_match = _key_frame_match(
        lambda index: look.network_albedo(densities[keys[index]]),
        [densities[key] for key in keys],
        target,
        scene,
        settings.seed,
        notes,
    )
    look.meta["fit_seconds"] = time.perf_counter() - started
    return look


@dataclass(frozen=True)
class _FitScene:
    """What a look's fit renders its key frames with: the density scale, the orbit's radius, the light."""

    density_scale: float
    camera_distance: float
    radiance: float


@dataclass
class _TunedParameters:
    """What a look's fit changes (the network's copy with its tuned decoder convolutions, the free kernels,
    the texture) and its optimizer."""

    network: object
    device: object  # torch.device
    free: dict
    texture: object
    optimizer: object

    def albedo(self, frame: dict, whole: bool = True):
        from ..model.skpn import StylizingKernels

        return frame_albedo(self.network, frame, StylizingKernels(self.free), self.texture, whole)


def _key_frames(densities: list, key_frames) -> list[int]:
    """The frames a look is fitted on: ``key_frames``, checked, or ``default_key_frames`` of the frames
    that hold medium enough to stylize (a simulation's frames before its emitter starts hold none)."""
    from ..stylizer import frame_list, holding_frames

    holding = holding_frames(densities)
    if not holding:
        raise ValueError("None of the frames holds medium enough to fit a look on.")
    if key_frames is None:
        return [holding[index] for index in default_key_frames(len(holding))]
    keys = sorted(set(int(k) for k in key_frames))
    if not keys or not all(0 <= k < len(densities) for k in keys):
        raise ValueError(f"Key frames {keys} must lie within the sequence's frames 0-{len(densities) - 1}.")
    empty = [k for k in keys if k not in holding]
    if empty:
        raise ValueError(
            f"Key frame(s) {frame_list(empty)} hold too little medium to fit a look on; frames {frame_list(holding)} "
            "hold enough (--key-frames)."
        )
    return keys


def _tuned_parameters(stylizer, style, target: np.ndarray, shape: tuple, settings: LookSettings):
    """The network's copy and the parameters a look's fit tunes on key frames of ``shape``
    (``_TunedParameters``), started as ``settings`` say."""

    from ..adam import Adam

    device = stylizer.device
    # A look's own texture does what the network's noise site does, fitted to the style: started with the
    # site's noise, looks came out worse (docs/decisions/2026-12-02-noise-site.md), so a look starts without it.
    initial = stylizer.kernels(style).without_noise()
    network = copy.deepcopy(stylizer.trained.model).float().eval()
    for parameter in network.parameters():
        parameter.requires_grad_(False)
    tuned = []
    for index in settings.tune_decoder:
        for parameter in network.decoder[index].parameters():
            parameter.requires_grad_(True)
            tuned.append(parameter)
    free = {
        site: {
            key: value.detach().clone().float().requires_grad_(key != "bias" and site in settings.tune_sites)
            for key, value in kernel.items()
        }
        for site, kernel in initial.sites.items()
    }
    parameters = [value for kernel in free.values() for value in kernel.values() if value.requires_grad] + tuned
    groups = [{"params": parameters, "lr": settings.lr}]
    texture = None
    if settings.texture_side:
        longest = max(shape)
        texels = tuple(max(1, round(n * settings.texture_side / longest)) for n in shape)
        start = solid_texture_start(target, texels, settings.texture_start_strength, settings.seed)
        texture = start.to(device).requires_grad_(True)
        groups.append({"params": [texture], "lr": settings.texture_lr})
    return _TunedParameters(network, device, free, texture, Adam(groups))


def _key_frame_match(key_albedo, key_densities: list, target, scene: _FitScene, seed: int, notes: list | None):
    """The colour match fitted on the first key frame the layer sees (``key_albedo(index)``: the albedo
    of key frame ``index``); a simulation's first frame can be a wisp too thin to see."""
    from ..colour_match import InvisibleMedium, fit_colour_match

    for index, density in enumerate(key_densities):
        try:
            return fit_colour_match(
                key_albedo(index),
                density,
                target,
                density_scale=scene.density_scale,
                radiance=scene.radiance,
                camera_distance=scene.camera_distance,
                seed=seed,
            )
        except InvisibleMedium:
            continue
    if notes is not None:
        notes.append("the look has no colour match: its key frames are too thin to be seen at this density scale")
    return None


def _fit_steps(fit, frames, prepared_densities, target, scene, settings, notes, progress) -> list[float]:
    """The fit's Adam steps (``fit.fit_steps``, the loop every albedo fit shares) on ``frames``
    (``prepare_frame``'s, in turn) through the fast layer against the sliced objective with the body mask,
    plus the smoothness term; a fit that diverges keeps its lowest loss's values. Returns each step's loss."""
    from ..bridge_torch import render_views
    from ..fit import fit_steps
    from ..model.features import square_style
    from ..model.skpn import inference_precision
    from ..objective.losses import tv_loss
    from ..objective.masks import body_mask
    from ..objective.style import SLICED_STYLE_SIZE, SlicedObjective
    from ..scenes import CameraPath

    device = fit.device
    if inference_precision(device) == "bf16":
        # The fit's one convolution in bfloat16 where the hardware computes it natively, as the network
        # runs at inference: 2-4x faster on this project's CPU. The look is applied in float32.
        frames = [{**f, "folded": f["folded"].in_bfloat16()} if f["folded"] is not None else f for f in frames]
    objective = SlicedObjective(
        rgb_weight=settings.rgb_weight,
        patch_weight=settings.patch_weight,
        seed=settings.seed,
        structure_weight=settings.structure_weight,
        # The style's gradients at the scale a final render shows it: its side over the views' side.
        structure_style_pool=max(1, round(SLICED_STYLE_SIZE / settings.layer_res)),
    )
    targets = objective.targets(square_style(target, SLICED_STYLE_SIZE).to(device)[None])
    orbit, rng = CameraPath(distance=scene.camera_distance), np.random.default_rng(settings.seed)
    render = dict(steps=settings.layer_steps_per_ray, radiance=scene.radiance)

    def step_loss(step: int):
        frame, prepared = frames[step % len(frames)], prepared_densities[step % len(frames)]
        # A step's views evenly spaced from a random offset: better than independent draws in RGB, patch
        # and structure (docs/decisions/2026-12-03-look-fit-speed.md).
        views = orbit.sample_stratified(settings.views_per_step, rng)
        # On the crop window where the frame has one: the albedo outside it repeats its faces, which the
        # render takes as the padded grid (render_views' window); the smoothness term is the crop's
        # part of the grid's mean.
        window = frame["window"] if cropped_fit(frame) else None
        albedo = fit.albedo(frame, whole=window is None)
        images, white = render_views(albedo, prepared, views, settings.layer_res, white=True, window=window, **render)
        smoothness = tv_loss(albedo[None]) * (albedo[0].numel() / frame["grid"].size)
        return objective.loss(images[None], targets, body_mask(white)) + settings.tv_weight * smoothness

    fitted = fit_steps(step_loss, fit.optimizer, settings.steps, progress, keep_lowest=True)
    if fitted.kept_step is not None and notes is not None:
        lowest = fitted.losses[fitted.kept_step - 1]
        notes.append(
            f"the look's fit diverged (its last steps' loss above its start's): it keeps the values of "
            f"its lowest loss, {lowest:.4g}, at step {fitted.kept_step} of {len(fitted.losses)}"
        )
    return fitted.losses
