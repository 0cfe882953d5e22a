"""The user-facing API, mirroring ``python -m mistyle.render_final``.

    import mistyle
    density = mistyle.load_density("smoke.vol")                   # (Z, Y, X)
    albedo = mistyle.stylize(density, "marble.png")               # (Z, Y, X, 3) in [0, 1]
    image = mistyle.render(density, albedo, view=0.25, res=256)   # (256, 256, 3) linear RGB
    png_values = mistyle.display(image)                           # the PNGs' tone curve

``stylize`` runs the trained SKPN feed-forward (the bundled checkpoint unless one is named) on
numpy arrays of any ``D, H, W``, single frames ``(Z, Y, X)`` or sequences ``(T, Z, Y, X)``; frames
are stylized independently, as in the paper. ``render`` path-traces the heterogeneous medium
with Mitsuba's ``volpath`` in ``llvm_ad_rgb`` on the CPU (``cuda_ad_rgb`` with ``device="cuda"``).
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


def validate_scale_structures(factor, name: str = "scale_structures") -> float:
    """The structure-scale factor, in ``SCALE_STRUCTURES_RANGE``; ``ValueError`` naming ``name``."""
    low, high = SCALE_STRUCTURES_RANGE
    if not (np.isfinite(factor) and low <= factor <= high):
        raise ValueError(f"{name} must lie in [{low}, {high}], got {factor}.")
    return float(factor)

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

    def __call__(self, density, style, scale_structures: float = 1.0, notes: list | None = None) -> np.ndarray:
        from .volume import validate_density

        style = load_style(style, notes)
        array = np.asarray(density)
        sequence = array.ndim == 4 and array.shape[-1] != 1
        frames = array if sequence else array[None]
        validate_scale_structures(scale_structures)
        inputs = self.style_inputs(style)
        albedos = []
        for index, frame in enumerate(frames):
            grid = validate_density(frame, name=f"density frame {index}" if sequence else "density")
            if not grid.any():
                raise ValueError(f"{'Frame ' + str(index) + ' of the density' if sequence else 'The density'} is all zero; "
                                 "there is no medium to stylize.")
            albedos.append(self._one(grid, inputs, scale_structures))
        return np.stack(albedos) if sequence else albedos[0]

    def _one(self, grid: np.ndarray, inputs, scale_structures: float) -> np.ndarray:
        import torch
        import torch.nn.functional as F

        shape = grid.shape
        density = torch.from_numpy(grid)[None, None].to(self.device)
        if scale_structures != 1.0:
            size = tuple(max(4, round(n * scale_structures)) for n in shape)
            density = F.interpolate(density, size=size, mode="trilinear", align_corners=False)
        with torch.no_grad():
            albedo = self.trained.model(density, inputs)
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
               coat_mesh=None, device: str = "cpu", seed: int = 0, progress=None) -> tuple[list[np.ndarray], list[float]]:
    """``render`` for several ``View``s of one scene: ``([(res, res, 3)] images, [seconds per view])``.

    ``progress(done, count, seconds)`` is called after each view when given.
    """
    from .backend import use_variant
    from .scenes import LightSpec, pathtraced_scene
    from .volume import validate_albedo, validate_density

    mi = use_variant(device)
    grid = validate_density(density)
    colours = validate_albedo(albedo, grid.shape)
    if not 1 <= res <= 8192 or spp < 1:
        raise ValueError(f"Need 1 <= res <= 8192 and spp >= 1, got res={res}, spp={spp}.")
    light = light if isinstance(light, LightSpec) else LightSpec.parse(light)
    scene = mi.load_dict(pathtraced_scene(grid, colours, views, res=res, density_scale=density_scale, spp=spp,
                                          max_depth=max_depth, light=light, coat_ior=coat_ior, coat_mesh=coat_mesh,
                                          seed=seed))
    images, seconds = [], []
    for index in range(len(views)):
        started = time.perf_counter()
        images.append(np.array(mi.render(scene, sensor=index), dtype=np.float32))
        seconds.append(time.perf_counter() - started)
        if progress is not None:
            progress(index + 1, len(views), seconds[-1])
    return images, seconds
