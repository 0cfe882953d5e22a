"""The user-facing API: ``stylize`` a density with a picture, ``render`` the result with Mitsuba.

    import mistyle
    albedo = mistyle.stylize(density, "marble.png")              # (Z, Y, X) -> (Z, Y, X, 3)
    image = mistyle.render(density, albedo, res=256, spp=64)       # (256, 256, 3) linear RGB

``stylize`` runs the trained SKPN feed-forward (the bundled checkpoint unless one is named) on
numpy arrays of any ``D, H, W``, single frames ``(Z, Y, X)`` or sequences ``(T, Z, Y, X)``; frames
are stylized independently, as in the paper. ``render`` path-traces the heterogeneous medium
with Mitsuba's ``volpath`` in ``llvm_ad_rgb`` on the CPU (``cuda_ad_rgb`` with ``device="cuda"``).
Images are linear radiance; ``display`` maps them to the training tone curve for PNGs.
"""

from __future__ import annotations

import functools
import os
import time
from pathlib import Path

import numpy as np

PACKAGE = Path(__file__).resolve().parent
DEFAULT_CHECKPOINT = PACKAGE / "checkpoints" / "skpn_cpu.pt"
_EXTRACTOR_KIND = {"vgg16-imagenet": "vgg16", "vgg16-random": "vgg16-random", "filterbank": "filterbank"}


def load_style(style, notes: list | None = None) -> np.ndarray:
    """A style image as float32 ``(H, W, 3)`` in [0, 1] from a path or an array.

    Arrays may be ``uint8``, ``uint16`` or float in [0, 1], with 1, 3 or 4 channels (alpha is
    composited over black, grey is replicated). Each conversion is described in ``notes``.
    """
    from .data.styles import MIN_SIZE, load_image

    notes = [] if notes is None else notes
    if isinstance(style, (str, os.PathLike)):
        return load_image(style, notes=notes)
    array = np.asarray(style)
    if array.ndim == 2:
        array = array[..., None]
    if array.ndim != 3 or array.shape[-1] not in (1, 3, 4):
        raise ValueError(f"A style image array must be (H, W, 3) (or 1 or 4 channels), got shape {array.shape}.")
    if array.dtype == np.uint8:
        array = array.astype(np.float32) / 255.0
    elif array.dtype == np.uint16:
        array = array.astype(np.float32) / 65535.0
        notes.append("16-bit style image scaled to [0, 1]")
    else:
        array = array.astype(np.float32)
        if not np.all(np.isfinite(array)) or array.min() < 0 or array.max() > 1:
            raise ValueError("A float style image must hold finite values in [0, 1] (display-encoded sRGB).")
    if array.shape[-1] == 1:
        array = np.repeat(array, 3, axis=-1)
        notes.append("greyscale style image replicated to RGB")
    elif array.shape[-1] == 4:
        array = array[..., :3] * array[..., 3:]
        notes.append("style image alpha composited over black (the renders' background)")
    if min(array.shape[:2]) < MIN_SIZE:
        raise ValueError(f"The style image is {array.shape[1]}x{array.shape[0]} pixels; it needs at least {MIN_SIZE}x{MIN_SIZE}.")
    return np.ascontiguousarray(array)


class Stylizer:
    """A loaded checkpoint: ``stylizer(density, style) -> albedo``; see ``stylize``."""

    def __init__(self, checkpoint=None, device: str = "cpu", vgg_weights=None):
        import torch

        from .scenes import DEFAULT_DENSITY_SCALE
        from .train.features import make_extractor
        from .train.trainer import load_checkpoint, model_from_checkpoint

        path = Path(checkpoint) if checkpoint is not None else DEFAULT_CHECKPOINT
        if checkpoint is None and not path.is_file():
            raise ValueError(f"The bundled checkpoint {path} is missing; train one with "
                             "`python -m mistyle.train --config configs/cpu.toml --out runs/cpu` and pass --checkpoint.")
        self.path = path
        checkpoint = load_checkpoint(path)
        self.model, self.config = model_from_checkpoint(checkpoint, path)
        extractor_name = checkpoint["extractor"]
        self.density_scale = float(checkpoint.get("density_scale", DEFAULT_DENSITY_SCALE))
        kind = _EXTRACTOR_KIND.get(extractor_name)
        if kind is None:
            raise ValueError(f"{path} was trained with an unknown feature extractor {extractor_name!r}.")
        self.extractor = make_extractor(kind, vgg_weights)
        if tuple(self.extractor.channels) != tuple(self.config.model.style_channels):
            raise ValueError(f"{path} expects style features of widths {self.config.model.style_channels}, "
                             f"the {extractor_name} extractor gives {self.extractor.channels}.")
        self.device = torch.device(device)
        self.model.to(self.device)
        self.extractor.to(self.device)

    def style_levels(self, style: np.ndarray):
        import torch

        from .train.dataset import square_style

        image = square_style(style, self.config.data.style_size)[None].to(self.device)
        with torch.no_grad():
            return list(self.extractor(image))

    def __call__(self, density, style, scale_structures: float = 1.0, notes: list | None = None) -> np.ndarray:
        from .volume import validate_density

        style = load_style(style, notes)
        array = np.asarray(density)
        sequence = array.ndim == 4 and array.shape[-1] != 1
        frames = array if sequence else array[None]
        if not np.isfinite(scale_structures) or not 0.125 <= scale_structures <= 8:
            raise ValueError(f"scale_structures must lie in [0.125, 8], got {scale_structures}.")
        levels = self.style_levels(style)
        albedos = []
        for index, frame in enumerate(frames):
            grid = validate_density(frame, name=f"density frame {index}" if sequence else "density")
            if not grid.any():
                raise ValueError(f"{'Frame ' + str(index) + ' of the density' if sequence else 'The density'} is all zero; "
                                 "there is no medium to stylize.")
            albedos.append(self._one(grid, levels, scale_structures))
        return np.stack(albedos) if sequence else albedos[0]

    def _one(self, grid: np.ndarray, levels, scale_structures: float) -> np.ndarray:
        import torch
        import torch.nn.functional as F

        shape = grid.shape
        density = torch.from_numpy(grid)[None, None].to(self.device)
        if scale_structures != 1.0:
            size = tuple(max(4, round(n * scale_structures)) for n in shape)
            density = F.interpolate(density, size=size, mode="trilinear", align_corners=False)
        with torch.no_grad():
            albedo = self.model(density, levels)
            if tuple(albedo.shape[2:]) != shape:
                albedo = F.interpolate(albedo, size=shape, mode="trilinear", align_corners=False)
        return np.ascontiguousarray(albedo[0].permute(1, 2, 3, 0).clamp(0, 1).cpu().numpy(), dtype=np.float32)


@functools.lru_cache(maxsize=2)
def _stylizer(checkpoint, device, vgg_weights) -> Stylizer:
    return Stylizer(checkpoint, device, vgg_weights)


def stylize(density, style_image, checkpoint=None, scale_structures: float = 1.0, device: str = "cpu",
            vgg_weights=None) -> np.ndarray:
    """Albedo for ``density`` in the look of ``style_image``, feed-forward.

    Args:
        density: ``(Z, Y, X)`` or a sequence ``(T, Z, Y, X)``, finite, >= 0, not all zero.
        style_image: a path, or an ``(H, W, 3)`` array (uint8, uint16 or float in [0, 1]).
        checkpoint: a ``python -m mistyle.train`` checkpoint; default: the bundled one.
        scale_structures: resample the density by this factor before stylizing (paper Sec. 5.5):
            > 1 makes the style's structures smaller relative to the volume.

    Returns:
        ``(Z, Y, X, 3)`` (or ``(T, Z, Y, X, 3)``) float32 albedo in [0, 1].
    """
    key = None if checkpoint is None else str(Path(checkpoint).resolve())
    return _stylizer(key, device, vgg_weights)(density, style_image, scale_structures)


def display(image: np.ndarray) -> np.ndarray:
    """Linear radiance ``(..., 3)`` -> display values in [0, 1] with the training tone curve."""
    import torch

    from .train.losses import tone_map

    return tone_map(torch.from_numpy(np.asarray(image, dtype=np.float32))).clamp(0, 1).numpy()


def render(density, albedo, view=None, res: int = 256, spp: int = 64, max_depth: int = -1,
           density_scale: float | None = None, light: str = "constant", coat_ior: float | None = None,
           coat_mesh=None, device: str = "cpu", seed: int = 0) -> np.ndarray:
    """Path-trace the medium with Mitsuba's ``volpath``; returns ``(res, res, 3)`` linear RGB.

    Args:
        view: a ``mistyle.scenes.View``; default: the training orbit's first held-out view.
        max_depth: ``-1`` full multiple scattering; ``2`` single scattering.
        density_scale: extinction per unit density (default: the training scale, 20).
        light: ``constant[:Le]``, ``envmap:<file.exr>[:scale]``, ``point:x,y,z[:I]`` or ``area[:L]``.
        coat_ior: a smooth dielectric boundary of this index of refraction (e.g. 1.5); ``None``: none.
    """
    return path_trace(density, albedo, [view] if view is not None else None, res, spp, max_depth, density_scale,
                        light, coat_ior, coat_mesh, device, seed)[0][0]


def path_trace(density, albedo, views=None, res: int = 256, spp: int = 64, max_depth: int = -1,
                 density_scale: float | None = None, light: str = "constant", coat_ior: float | None = None,
                 coat_mesh=None, device: str = "cpu", seed: int = 0, progress=None) -> tuple[list[np.ndarray], list[float]]:
    """``render`` for several views of one scene: ``([(res, res, 3)] images, [seconds per view])``."""
    from .backend import use_variant
    from .scenes import DEFAULT_DENSITY_SCALE, CameraPath
    from .scenes.final import LightSpec, final_scene
    from .volume import validate_albedo, validate_density

    mi = use_variant(device)
    grid = validate_density(density)
    colours = validate_albedo(albedo, grid.shape)
    if res < 1 or res > 8192 or spp < 1:
        raise ValueError(f"Need 1 <= res <= 8192 and spp >= 1, got res={res}, spp={spp}.")
    views = views or CameraPath().turntable(1, offset=0.0625)
    scale = DEFAULT_DENSITY_SCALE if density_scale is None else density_scale
    scene = mi.load_dict(final_scene(grid, scale, colours, views, res, res, spp=spp, max_depth=max_depth,
                                     light=light if isinstance(light, LightSpec) else LightSpec.parse(light), coat_ior=coat_ior, coat_mesh=coat_mesh, seed=seed))
    images, seconds = [], []
    for index in range(len(views)):
        started = time.perf_counter()
        images.append(np.array(mi.render(scene, sensor=index), dtype=np.float32))
        seconds.append(time.perf_counter() - started)
        if progress is not None:
            progress(index + 1, len(views), seconds[-1])
    return images, seconds
