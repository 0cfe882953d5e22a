"""The user-facing API, mirroring ``python -m mistyle.render_final``.

    import mistyle
    density = mistyle.load_density("smoke.vol")                   # (Z, Y, X)
    albedo = mistyle.stylize(density, "marble.png")               # (Z, Y, X, 3) in [0, 1]
    image = mistyle.render(density, albedo, view=0.25, res=256)   # (256, 256, 3) linear RGB
    png_values = mistyle.display(image)                           # the PNGs' tone curve

``stylize`` runs the trained SKPN feed-forward (the bundled checkpoint unless one is named) on
numpy arrays of any ``D, H, W``, single frames ``(Z, Y, X)`` or sequences ``(T, Z, Y, X)``; frames
are stylized independently, as in the paper. ``strength`` fades the style towards a uniform grey
medium and a list of ``(style, weight)`` pairs mixes styles; both act on the predicted stylizing
kernels (``Stylizer.kernels``, ``Stylizer.weakened``), not on finished albedos:

    albedo = mistyle.stylize(density, [("wave.png", 0.7), ("starry.png", 0.3)], strength=0.5)

``render`` path-traces the heterogeneous medium with Mitsuba's ``volpath`` in ``llvm_ad_rgb`` on the
CPU (``cuda_ad_rgb`` with ``device="cuda"``).
"""

from __future__ import annotations

import functools
import time
from pathlib import Path

import numpy as np

from .conventions import DEFAULT_DENSITY_SCALE, HELD_OUT_VIEW, ORBIT_DISTANCE
from .display import display
from .io import load_density, load_style

PACKAGE = Path(__file__).resolve().parent
DEFAULT_CHECKPOINT = PACKAGE / "checkpoints" / "skpn_cpu.pt"
SCALE_STRUCTURES_RANGE = (0.125, 8.0)
# Rec. 709 luma of display RGB: the brightness a neutral (strength 0) medium keeps from the style.
LUMA_WEIGHTS = np.array([0.2126, 0.7152, 0.0722])


def validate_scale_structures(factor, name: str = "scale_structures") -> float:
    """The structure-scale factor, in ``SCALE_STRUCTURES_RANGE``; ``ValueError`` naming ``name``."""
    low, high = SCALE_STRUCTURES_RANGE
    if not (np.isfinite(factor) and low <= factor <= high):
        raise ValueError(f"{name} must lie in [{low}, {high}], got {factor}.")
    return float(factor)


def validate_strength(strength, name: str = "strength") -> float:
    """A style strength in [0, 1]; ``ValueError`` naming ``name``."""
    if not (np.isfinite(strength) and 0.0 <= strength <= 1.0):
        raise ValueError(f"{name} must lie in [0, 1] (0: a uniform grey medium, 1: the full style), got {strength}.")
    return float(strength)


def style_parts(style) -> list[tuple[object, float]]:
    """``style`` as ``[(image or path, weight)]``: one image or path, or a list of ``(style, weight)``."""
    if isinstance(style, (list, tuple)) and style and all(isinstance(p, tuple) and len(p) == 2 for p in style):
        weights = [float(w) for _, w in style]
        if not all(np.isfinite(w) and w >= 0 for w in weights) or sum(weights) <= 0:
            raise ValueError(f"Style mix weights must be >= 0 with a positive sum, got {weights}.")
        return [(image, float(w)) for image, w in style]
    return [(style, 1.0)]


def style_target(images: list[np.ndarray], weights, height: int = 256) -> np.ndarray:
    """The picture a style's look is measured and refined against: the image itself, or for a mix a
    mosaic ``(height, W, 3)`` of its images side by side, each given a width in proportion to its
    weight (scaled to ``height``, tiled across its strip), so every style's colours and patterns
    count as much as its weight."""
    from PIL import Image

    if len(images) == 1:
        return images[0]
    weights = np.asarray(weights, dtype=np.float64) / np.sum(weights)
    strips = []
    for image, weight in zip(images, weights):
        width = round(height * len(images) * weight)
        if width < 1:
            continue
        scaled = np.asarray(Image.fromarray((image * 255 + 0.5).astype(np.uint8)).resize(
            (max(1, round(image.shape[1] * height / image.shape[0])), height), Image.LANCZOS), dtype=np.float32) / 255
        repeats = -(-width // scaled.shape[1])
        strips.append(np.tile(scaled, (1, repeats, 1))[:, :width])
    return np.concatenate(strips, axis=1)


__all__ = ["Stylizer", "display", "load_density", "load_style", "path_trace", "render", "stylize"]


class Stylizer:
    """A loaded checkpoint: ``stylizer(density, style) -> albedo``; see ``stylize``.

    Attributes:
        trained: the checkpoint's ``mistyle.model.checkpoint.TrainedModel`` (network, config,
            extractor, density scale).
    """

    def __init__(self, checkpoint=None, device: str = "cpu", vgg_weights=None):
        import torch

        from .model.checkpoint import load_model

        path = Path(checkpoint) if checkpoint is not None else DEFAULT_CHECKPOINT
        if not path.is_file():
            if checkpoint is None:
                raise ValueError(f"The bundled checkpoint {path} is missing; train one with "
                                 "`python -m mistyle.train --config configs/cpu.toml --out runs/cpu` and pass --checkpoint.")
            raise ValueError(f"Checkpoint {path} does not exist; give a file written by `python -m mistyle.train` "
                             "(e.g. runs/cpu/final.pt), or leave --checkpoint out for the bundled one.")
        self.trained = load_model(path, vgg_weights)
        self.device = torch.device(device)
        self.trained.model.to(self.device)
        self.trained.extractor.to(self.device)

    @property
    def path(self) -> Path:
        return self.trained.path

    @property
    def config(self):
        return self.trained.config

    @property
    def extractor(self):
        return self.trained.extractor

    @property
    def density_scale(self) -> float:
        return self.trained.density_scale

    def style_tensor(self, style: np.ndarray):
        """``(H, W, 3)`` style -> the ``(3, S, S)`` square the network and the objective see."""
        from .model.features import square_style

        return square_style(style, self.config.data.style_size)

    def style_inputs(self, style: np.ndarray):
        """What the network reads of ``style`` (``model.skpn.StyleInputs``)."""
        return self.trained.model.encode_style(self.style_tensor(style)[None].to(self.device), self.extractor)

    def kernels(self, style, notes: list | None = None):
        """The stylizing kernels (``model.skpn.StylizingKernels``) the network applies for ``style``:
        one image or path, or a mix ``[(style, weight)]``, whose kernels are blended with the
        weights normalised to sum 1."""
        import torch

        from .model.skpn import StylizingKernels

        model = self.trained.model
        with torch.no_grad():
            return StylizingKernels.blend([(model.predict_kernels(self.style_inputs(load_style(image, notes))), weight)
                                           for image, weight in style_parts(style)])

    def weakened(self, kernels, grid: np.ndarray, strength: float):
        """``kernels`` at ``strength``: blended with ``SKPN.neutral_kernels`` whose grey is the luma of the
        full-strength albedo's density-weighted mean on ``grid``, so that fading the style out keeps
        the medium's brightness and removes its hues and patterns (0: uniform grey, 1: ``kernels``)."""
        from .model.skpn import StylizingKernels

        if validate_strength(strength) == 1.0:
            return kernels
        return StylizingKernels.blend([(kernels, strength), (self.neutral(kernels, grid), 1.0 - strength)])

    def neutral(self, kernels, grid: np.ndarray):
        """``SKPN.neutral_kernels`` of ``kernels`` whose grey is the luma of the density-weighted mean of
        the albedo ``kernels`` give on ``grid`` (what ``weakened`` fades towards)."""
        full = self._one(grid, kernels, 1.0)
        grey = float(np.tensordot(grid / grid.sum(), full, axes=3) @ LUMA_WEIGHTS)
        return self.trained.model.neutral_kernels(kernels, grey)

    def __call__(self, density, style, scale_structures: float = 1.0, notes: list | None = None,
                 strength: float = 1.0, match_colours: bool = True) -> np.ndarray:
        """Albedo ``(Z, Y, X, 3)`` (or ``(T, Z, Y, X, 3)``) of ``density`` for ``style`` (see ``kernels``)
        at ``strength`` (see ``weakened``; a sequence's grey comes from its first frame).

        ``match_colours``: give the network's arrangement the style's colours (``colour_match``; for a
        mix, the colours of ``style_target``), moved ``strength`` of the way; a sequence shares the map
        fitted on its first frame. A medium too thin to be seen keeps the network's colours (said in
        ``notes``). False: the network's albedo as predicted."""
        from .volume import validate_density

        array = np.asarray(density)
        sequence = array.ndim == 4 and array.shape[-1] != 1
        frames = array if sequence else array[None]
        validate_scale_structures(scale_structures)
        validate_strength(strength)
        parts = [(load_style(image, notes), weight) for image, weight in style_parts(style)]
        inputs = self.kernels(parts)
        grids, albedos = [], []
        for index, frame in enumerate(frames):
            grid = validate_density(frame, name=f"density frame {index}" if sequence else "density")
            if not grid.any():
                raise ValueError(f"{'Frame ' + str(index) + ' of the density' if sequence else 'The density'} is all zero; "
                                 "there is no medium to stylize.")
            if index == 0:
                inputs = self.weakened(inputs, grid, strength)
            grids.append(grid)
            albedos.append(self._one(grid, inputs, scale_structures))
        if match_colours and strength > 0:
            target = style_target([image for image, _ in parts], [weight for _, weight in parts])
            albedos = self.match_colours(albedos, grids, target, strength, notes)
        return np.stack(albedos) if sequence else albedos[0]

    def match_colours(self, albedos: list, grids: list, target: np.ndarray, strength: float = 1.0,
                      notes: list | None = None) -> list:
        """The frames' albedos ``[(Z, Y, X, 3)]`` on ``grids`` with the colours of the picture ``target (H, W, 3)``
        (``colour_match``), through the map fitted on the first frame, moved ``strength`` of the way. A medium
        too thin to be seen keeps its albedos (said in ``notes``)."""
        from .colour_match import InvisibleMedium, fit_colour_match

        render = self.config.render
        try:
            match = fit_colour_match(albedos[0], grids[0], target, density_scale=self.density_scale,
                                     radiance=render.radiance, camera_distance=render.camera_distance)
        except InvisibleMedium:
            if notes is not None:
                notes.append("colour match skipped: the medium is too thin to be seen at this density scale, "
                             "so the network's own colours are kept")
            return albedos
        return [match.apply(albedo, grid, strength) for albedo, grid in zip(albedos, grids)]

    def _one(self, grid: np.ndarray, inputs, scale_structures: float) -> np.ndarray:
        import torch
        import torch.nn.functional as F

        shape = grid.shape
        density = torch.from_numpy(grid)[None, None].to(self.device)
        if scale_structures != 1.0:
            size = tuple(max(4, round(n * scale_structures)) for n in shape)
            density = F.interpolate(density, size=size, mode="trilinear", align_corners=False)
        with torch.no_grad():
            albedo = self.trained.model.infer(density, inputs)  # bfloat16, empty space cropped: SKPN.infer
            if tuple(albedo.shape[2:]) != shape:
                albedo = F.interpolate(albedo, size=shape, mode="trilinear", align_corners=False)
        return np.ascontiguousarray(albedo[0].permute(1, 2, 3, 0).clamp(0, 1).cpu().numpy(), dtype=np.float32)


@functools.lru_cache(maxsize=2)
def _stylizer(checkpoint, device, vgg_weights) -> Stylizer:
    return Stylizer(checkpoint, device, vgg_weights)


def stylize(density, style_image, checkpoint=None, scale_structures: float = 1.0, device: str = "cpu",
            vgg_weights=None, strength: float = 1.0, match_colours: bool = True) -> np.ndarray:
    """Albedo for ``density`` in the look of ``style_image``, feed-forward: the network's arrangement
    with the style's colours (``colour_match``; no gradient step).

    Args:
        density: ``(Z, Y, X)`` or a sequence ``(T, Z, Y, X)``, finite, >= 0, not all zero.
        style_image: a path, or an ``(H, W, 3)`` array (uint8, uint16 or float in [0, 1]), or a mix
            ``[(style, weight), ...]`` (weights >= 0, normalised to sum 1).
        strength: 0 gives a uniform grey medium of the styled one's brightness, 1 the full style.
        checkpoint: a ``python -m mistyle.train`` checkpoint; default: the bundled one.
        scale_structures: resample the density by this factor before stylizing (paper Sec. 5.5):
            > 1 makes the style's structures smaller relative to the volume.
        match_colours: False gives the network's albedo as predicted, without the colour match.

    Returns:
        ``(Z, Y, X, 3)`` (or ``(T, Z, Y, X, 3)``) float32 albedo in [0, 1].
    """
    key = None if checkpoint is None else str(Path(checkpoint).resolve())
    return _stylizer(key, device, vgg_weights)(density, style_image, scale_structures, strength=strength,
                                               match_colours=match_colours)


def render(density, albedo, view: float = HELD_OUT_VIEW, res: int = 256, spp: int = 64, max_depth: int = -1,
           density_scale: float = DEFAULT_DENSITY_SCALE, light: str = "constant", coat_ior: float | None = None,
           coat_mesh=None, camera_distance: float = ORBIT_DISTANCE, device: str = "cpu", seed: int = 0) -> np.ndarray:
    """Path-trace the medium with Mitsuba's ``volpath``; returns ``(res, res, 3)`` linear RGB.

    Args:
        view: the camera's position on the orbit in [0, 1), as ``--view`` (default: the held-out
            view of evaluations), or a ``mistyle.scenes.View``.
        max_depth: ``-1`` full multiple scattering; ``2`` single scattering.
        density_scale: extinction per unit density (default: the training scale).
        light: ``constant[:Le]``, ``envmap:<file.exr>[:scale]``, ``point:x,y,z[:I]`` or ``area[:L]``.
        coat_ior: a smooth dielectric boundary of this index of refraction (e.g. 1.5); ``None``: none.
        camera_distance: the orbit's radius (the medium box's longest side is 1).
    """
    from .scenes import CameraPath, View
    from .scenes.cameras import validate_orbit_position

    camera = view if isinstance(view, View) else CameraPath(distance=camera_distance).view(validate_orbit_position(view))
    images, _ = path_trace(density, albedo, [camera], res=res, spp=spp, max_depth=max_depth, density_scale=density_scale,
                           light=light, coat_ior=coat_ior, coat_mesh=coat_mesh, device=device, seed=seed)
    return images[0]


def path_trace(density, albedo, views, *, res: int = 256, spp: int = 64, max_depth: int = -1,
               density_scale: float = DEFAULT_DENSITY_SCALE, light="constant", coat_ior: float | None = None,
               coat_mesh=None, device: str = "cpu", seed: int = 0, progress=None,
               bricks: int | None = None) -> tuple[list[np.ndarray], list[float]]:
    """``render`` for several ``View``s of one scene: ``([(res, res, 3)] images, [seconds per view])``.

    ``progress(done, count, seconds)`` is called after each view when given. ``bricks``: voxels per
    brick of the medium's majorant bricks (``scenes.bricks``; the same image in expectation, faster
    on sparse volumes), ``0`` for one medium; by default ``DEFAULT_BRICK``, and 0 under a coat.
    """
    from .backend import use_variant
    from .scenes import LightSpec, pathtraced_scene
    from .scenes.bricks import DEFAULT_BRICK
    from .volume import validate_albedo, validate_density

    mi = use_variant(device)
    grid = validate_density(density)
    colours = validate_albedo(albedo, grid.shape)
    if not 1 <= res <= 8192 or spp < 1:
        raise ValueError(f"Need 1 <= res <= 8192 and spp >= 1, got res={res}, spp={spp}.")
    light = light if isinstance(light, LightSpec) else LightSpec.parse(light)
    if bricks is None:
        bricks = 0 if coat_ior is not None else DEFAULT_BRICK
    scene = mi.load_dict(pathtraced_scene(grid, colours, views, res=res, density_scale=density_scale, spp=spp,
                                          max_depth=max_depth, light=light, coat_ior=coat_ior, coat_mesh=coat_mesh,
                                          seed=seed, bricks=bricks))
    images, seconds = [], []
    for index in range(len(views)):
        started = time.perf_counter()
        images.append(np.array(mi.render(scene, sensor=index), dtype=np.float32))
        seconds.append(time.perf_counter() - started)
        if progress is not None:
            progress(index + 1, len(views), seconds[-1])
    return images, seconds
