"""Solid textures: a 3-D colour field whose slices look like a picture.

    from mistyle.solid_texture import SolidTextureSettings, synthesise_solid_texture

    texture = synthesise_solid_texture(style)            # (64, 64, 64, 3) in [0, 1], about 3 s on 2 cores
    albedo = lay_over(texture, density)                  # stretched over the density's grid, (Z, Y, X, 3)

A solid texture is the volumetric analogue of a texture synthesised from an exemplar (Kopf et al. 2007):
every axis-aligned slice of it should be a plausible crop of the style. It is made here the way
texture synthesis by optimisation makes a picture (Heitz et al. 2021; Elnekave & Weiss 2022), with raw
pixels for features: the voxels are free variables, and each step takes a few random slices along each
axis, cuts them into ``patch x patch`` patches and pulls the patches' distribution towards the style's
patches by the sliced Wasserstein distance. It runs coarse to fine over a pyramid (``levels``) so that
large structures (bands, swirls) form on a small grid and the finer levels only add strokes and grain.

What it gives the product: structures the density alone does not dictate, with the style's own
orientations and scales, fixed in the medium's box and the same for every frame of a sequence. What it
is not: a render. Depth averaging in a thin medium and multiple scattering in a dense one change what a
viewer sees of it; the colour match (``colour_match``) and the look's fit (``look``) answer for that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .conventions import MAX_FIT_STEPS
from .volume import box_of

MIN_EXEMPLAR_SIDE = 8
"""The coarsest level's exemplar needs at least this many pixels along its shorter side for patches."""


@dataclass(frozen=True)
class SolidTextureSettings:
    """How a solid texture is synthesised; the defaults are the ``solid_texture`` baseline's."""

    side: int = 64  # texels along each axis of the cube
    exemplar_side: int = 96  # the style's longest side at the finest level: how large its strokes are in texels
    levels: int = 3  # pyramid levels, each half the size of the next
    patch: int = 5  # patch side in pixels at every level
    # Steps, patches and projections: about 2.7 s on 2 cores, its slices' structure distance to the style
    # within 0.04 of 4x the steps and patches at 9x the time (results/solid_texture_study/slices.json).
    steps: int = 60  # optimisation steps per level
    patches: int = 8192  # patches a step compares, at random places in slices across each axis
    projections: int = 64  # random projections per step
    pool: int = 256  # directions along which the style's patches are sorted once per level
    lr: float = 0.03
    seed: int = 0

    def __post_init__(self):
        if not 8 <= self.side <= 256:
            raise ValueError(f"A solid texture's side must lie in [8, 256] texels, got {self.side}.")
        if not 1 <= self.levels <= 5:
            raise ValueError(f"A solid texture has 1 to 5 levels, got {self.levels}.")
        if self.side >> (self.levels - 1) < self.patch + 2:
            raise ValueError(
                f"A {self.side}^3 texture has too few texels at its coarsest of {self.levels} levels for "
                f"{self.patch}x{self.patch} patches; use fewer levels or a larger side."
            )
        if self.patch < 1 or self.patch % 2 == 0:
            raise ValueError(f"The patch side must be odd and positive, got {self.patch}.")
        if self.exemplar_side < self.patch:
            raise ValueError(f"exemplar_side must be at least the patch side, got {self.exemplar_side}.")
        if not 0 <= self.steps <= MAX_FIT_STEPS:
            raise ValueError(f"steps must lie in [0, {MAX_FIT_STEPS}], got {self.steps}.")
        if self.patches < 3 or self.projections < 1 or self.pool < self.projections:
            raise ValueError("patches (at least 3) and projections must be positive, and pool at least projections.")


def exemplar_pyramid(style: np.ndarray, settings: SolidTextureSettings) -> list:
    """The style ``(H, W, 3)`` in [0, 1] at each level, coarsest first, as tensors ``(1, 3, h, w)``: the
    finest has ``exemplar_side`` pixels along its longest side, each coarser level half as many."""
    import torch
    import torch.nn.functional as F

    image = torch.from_numpy(np.ascontiguousarray(style, dtype=np.float32)).permute(2, 0, 1)[None]
    pyramid = []
    for level in range(settings.levels):
        longest = max(MIN_EXEMPLAR_SIDE, settings.exemplar_side >> (settings.levels - 1 - level))
        scale = longest / max(image.shape[-2:])
        size = tuple(max(MIN_EXEMPLAR_SIDE, round(n * scale)) for n in image.shape[-2:])
        pyramid.append(F.interpolate(image, size=size, mode="area" if scale < 1 else "bilinear"))
    return pyramid


def _random_patches(volume, count: int, size: int, generator):
    """``count`` patches ``(count, 3 * size * size)`` of ``volume (3, S, S, S)``, a third in slices across
    each axis, at random places: what ``masked_patches`` would cut from whole slices (channel, row,
    column order; rows and columns are the slice's two remaining axes in order), without cutting them."""
    import torch

    side = volume.shape[1]
    strides = (side * side, side, 1)
    offsets = torch.arange(size)
    flat = []
    for axis in range(3):
        row_stride, column_stride = (stride for a, stride in enumerate(strides) if a != axis)
        template = (offsets.view(size, 1) * row_stride + offsets.view(1, size) * column_stride).reshape(1, -1)
        here = count // 3 + (1 if axis < count % 3 else 0)
        at = torch.randint(0, side, (here, 1), generator=generator)
        corner = torch.randint(0, side - size + 1, (2, here, 1), generator=generator)
        flat.append(at * strides[axis] + corner[0] * row_stride + corner[1] * column_stride + template)
    flat = torch.cat(flat)  # (count, size * size) voxel indices; index_select's gradient is one index_add
    values = volume.reshape(3, -1).index_select(1, flat.reshape(-1)).reshape(3, count, size * size)
    return values.permute(1, 0, 2).reshape(count, -1)


def synthesise_solid_texture(style: np.ndarray, settings: SolidTextureSettings | None = None) -> np.ndarray:
    """A solid texture ``(S, S, S, 3)`` in [0, 1] (float32, the style's colour space) whose axis-aligned
    slices have the patch statistics of ``style (H, W, 3)`` in [0, 1] at every pyramid level."""
    import torch
    import torch.nn.functional as F

    from .adam import Adam
    from .objective.losses import masked_patches, project_target, sliced_wasserstein_loss
    from .stops import raise_if_requested

    settings = SolidTextureSettings() if settings is None else settings
    style = np.asarray(style, dtype=np.float32)
    if style.ndim != 3 or style.shape[2] != 3 or not np.isfinite(style).all():
        raise ValueError(f"A solid texture needs a finite RGB picture (H, W, 3), got shape {style.shape}.")
    generator = torch.Generator().manual_seed(settings.seed)
    exemplars = exemplar_pyramid(np.clip(style, 0.0, 1.0), settings)
    volume = None
    with torch.inference_mode(False):
        for level, exemplar in enumerate(exemplars):
            side = settings.side >> (settings.levels - 1 - level)
            if volume is None:
                # The style's mean colour with a little noise: the patches' distances decide the rest.
                mean = exemplar[0].reshape(3, -1).mean(dim=1)
                volume = mean.view(3, 1, 1, 1) + 0.02 * torch.randn((3,) + (side,) * 3, generator=generator)
            else:
                volume = F.interpolate(volume[None], size=(side,) * 3, mode="trilinear", align_corners=False)[0]
            volume = volume.detach().clone().requires_grad_(True)
            target = project_target(masked_patches(exemplar, None, settings.patch), settings.pool, generator)
            optimizer = Adam([{"params": [volume], "lr": settings.lr}])
            for step in range(settings.steps):
                raise_if_requested()
                # Decayed to zero within each level: Adam at a constant rate leaves every texel jittering
                # by about the rate, which the next level cannot tell from grain.
                optimizer.groups[0]["lr"] = settings.lr * 0.5 * (1.0 + math.cos(math.pi * step / settings.steps))
                patches = _random_patches(volume, settings.patches, settings.patch, generator)
                loss = sliced_wasserstein_loss(patches, target, settings.projections, generator)
                optimizer.zero_grad()
                loss.backward()
                optimizer.step()
                with torch.no_grad():
                    volume.clamp_(0.0, 1.0)
    return np.ascontiguousarray(volume.detach().permute(1, 2, 3, 0).numpy(), dtype=np.float32)


@lru_cache(maxsize=8)
def _cached(style_bytes: bytes, shape: tuple, settings: SolidTextureSettings) -> np.ndarray:
    texture = synthesise_solid_texture(np.frombuffer(style_bytes, np.float32).reshape(shape), settings)
    texture.flags.writeable = False
    return texture


def solid_texture_of(style: np.ndarray, settings: SolidTextureSettings | None = None) -> np.ndarray:
    """``synthesise_solid_texture``, made once per style and settings in a process (read-only): it depends
    on nothing else, so a benchmark's densities, a preview's changes of strength and the fits of one
    style share it."""
    style = np.ascontiguousarray(style, dtype=np.float32)
    return _cached(style.tobytes(), style.shape, SolidTextureSettings() if settings is None else settings)


def texture_in_box(texture: np.ndarray, shape: tuple) -> np.ndarray:
    """``texture (T, T, T, 3)`` resampled (trilinear) to a box of ``shape (Z, Y, X)`` voxels with the same
    texel size along every axis: the box's longest side spans the texture, shorter sides take its middle.
    ``(Z, Y, X, 3)``."""
    import torch
    import torch.nn.functional as F

    side = texture.shape[0]
    texels = [max(1, round(side * int(n) / max(int(m) for m in shape))) for n in shape]
    starts = [(side - t) // 2 for t in texels]
    cut = texture[tuple(slice(s, s + t) for s, t in zip(starts, texels))]
    values = torch.from_numpy(np.array(cut, dtype=np.float32)).permute(3, 0, 1, 2)[None]  # a copy: writable
    values = F.interpolate(values, size=tuple(int(n) for n in shape), mode="trilinear", align_corners=False)
    return np.ascontiguousarray(values[0].permute(1, 2, 3, 0).numpy())


def lay_over(texture: np.ndarray, density: np.ndarray) -> np.ndarray:
    """``texture (T, T, T, 3)`` over the bounding box of ``density (Z, Y, X)``'s occupied voxels
    (``texture_in_box``): ``(Z, Y, X, 3)``, zero outside the box."""
    density = np.asarray(density)
    albedo = np.zeros(density.shape + (3,), np.float32)
    box = box_of(density > 0)
    if box is None:
        return albedo
    albedo[box] = texture_in_box(texture, tuple(part.stop - part.start for part in box))
    return albedo
