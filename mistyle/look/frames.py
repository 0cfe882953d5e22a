"""What a look computes of a frame: the network's fixed part, the texture over the box (in place or
carried by a sequence's velocities), the albedo."""

from __future__ import annotations

import hashlib

import numpy as np

THUMBNAIL_SIDE = 256
"""The longest side of the style picture a look keeps: what renders from it are measured against."""


def frame_key(grid: np.ndarray) -> tuple:
    """A frame's identity for a look's cache of what its fit computed of the key frames."""
    data = np.ascontiguousarray(grid, dtype=np.float32).data
    return tuple(grid.shape), hashlib.blake2b(data, digest_size=16).digest()


def prepare_frame(
    network,
    grid: np.ndarray,
    scale_structures: float = 1.0,
    fixed_kernels=None,
    fixed_stage: str | None = None,
) -> dict:
    """What a look's network computes of one frame before its tuned parts: the (resampled, cropped)
    density's encoder features, its crop window and, with ``fixed_kernels``, the decoder up to ``fixed_stage``
    (``LookSettings.fixed_stage``: the values a fit that tunes only what follows reuses; at ``"body"``
    also what ``frame_albedo`` needs to fold the head into one convolution,
    ``SKPN.folded_head_logits``)."""
    import torch
    import torch.nn.functional as F

    from ..model.skpn import DEFAULT_CROP_MARGIN, occupied_window

    device = next(network.parameters()).device
    tensor = torch.from_numpy(np.ascontiguousarray(grid, dtype=np.float32))[None, None].to(device)
    if scale_structures != 1.0:
        size = tuple(max(4, round(n * scale_structures)) for n in grid.shape)
        tensor = F.interpolate(tensor, size=size, mode="trilinear", align_corners=False)
    size = tuple(tensor.shape[2:])
    window = occupied_window(tensor, DEFAULT_CROP_MARGIN)
    part = tensor if window is None else tensor[(..., *window)]
    fixed = {"body": None, "folded": None, "site": None, "logits": None}
    stages = ("body", "site", "logits")
    reached = stages.index(fixed_stage) + 1 if fixed_kernels is not None and fixed_stage is not None else 0
    with torch.no_grad():
        # A look's kernels never weigh the network's noise site (fit_look starts them without_noise and
        # does not tune it), so its fields, made for the whole grid, would add zeros.
        encoded = network.encode(part, noise_site=False)
        if reached >= 1:
            fixed["body"] = network.decode_body(encoded, fixed_kernels)
            if reached == 1 and network.folds_head(fixed_kernels):
                fixed["folded"] = network.fold_head_input(fixed["body"], encoded)
        if reached >= 2:
            fixed["site"] = network.head_site(fixed["body"], fixed_kernels, encoded)
        if reached >= 3:
            fixed["logits"] = network.head_logits(fixed["site"], fixed_kernels, encoded)
    return {"grid": grid, "size": size, "window": window, "encoded": encoded, **fixed}


def stretch_texture(texture, frame: dict, padded: tuple):
    """A look's ``texture (C, tz, ty, tx)`` stretched over the box of ``frame`` (``prepare_frame``) as
    trilinear interpolation (``align_corners=False``) to the frame's grid would, cut to its crop window
    and zero-padded to ``padded`` (the head's grid): ``(C, *padded)``.

    Trilinear interpolation is separable, so it runs as one small matrix product per axis, each of
    whose rows holds one voxel's two interpolation weights; a fit step's interpolation and its gradient
    cost several times less than ``F.interpolate`` of the whole grid. The matrices are kept in
    ``frame`` (per texture shape)."""
    import torch
    import torch.nn.functional as F

    channels, *texels = texture.shape
    key = ("stretch", tuple(texels), padded)
    matrices = frame.get(key)
    if matrices is None:
        window = frame["window"] or tuple(slice(0, n) for n in frame["size"])
        matrices = []
        for count, size, rows, length in zip(texels, frame["size"], window, padded):
            identity = torch.eye(count, dtype=torch.float32, device=texture.device)[None]
            weights = F.interpolate(identity, size=size, mode="linear", align_corners=False)[0].T[rows]
            matrices.append(F.pad(weights, (0, 0, 0, length - weights.shape[0])))
        frame[key] = matrices
    along_z, along_y, along_x = matrices
    values = torch.matmul(along_y, torch.matmul(texture, along_x.T))  # (C, tz, Y, X)
    return torch.matmul(along_z, values.reshape(channels, texels[0], -1)).reshape(channels, *padded)


def advected_texture(texture, frame: dict, padded: tuple, phases: list):
    """``stretch_texture`` of a texture that travels with the flow: ``texture (C, tz, ty, tx)`` read at the
    frame's advected ``phases`` (``advection.blend_phases``) over its whole grid, cut to its crop window
    and zero-padded to ``padded``: ``(C, *padded)``."""
    import torch.nn.functional as F

    from ..advection import blend_phases

    values = blend_phases(texture, phases, tuple(frame["size"]))
    if frame["window"] is not None:
        values = values[(slice(None), *frame["window"])]
    return F.pad(values, [p for n, m in reversed(list(zip(values.shape[1:], padded))) for p in (0, m - n)])


def frame_albedo(network, frame: dict, kernels, texture=None, whole: bool = True, phases: list | None = None):
    """A look's albedo ``(3, Z, Y, X)`` of a ``prepare_frame`` frame (differentiable in ``kernels``, the
    tuned decoder layers and ``texture (3, tz, ty, tx)``, which is stretched over the box whatever its
    resolution, or read through the frame's advected ``phases``, ``advection``). ``whole=False``: only over the frame's
    crop window where it has one and its grid was not resampled (``cropped_fit``), as
    ``render_views(..., window=frame["window"])`` takes it."""
    import torch.nn.functional as F

    from ..model.skpn import head_albedo, uncrop

    encoded = frame["encoded"]
    logits = frame["logits"]
    if logits is None and frame["folded"] is not None and network.folds_head(kernels):
        logits = network.folded_head_logits(frame["folded"], kernels, encoded)
    elif logits is None:
        site = frame["site"]
        if site is None:
            body = frame["body"] if frame["body"] is not None else network.decode_body(encoded, kernels)
            site = network.head_site(body, kernels, encoded)
        logits = network.head_logits(site, kernels, encoded)
    offset = None
    if texture is not None:
        padded = tuple(logits.shape[2:])
        offset = (
            stretch_texture(texture, frame, padded) if not phases else advected_texture(texture, frame, padded, phases)
        )[None]
    albedo = head_albedo(logits if offset is None else logits + offset, encoded.size)
    if not whole and cropped_fit(frame):
        return albedo[0]
    albedo = uncrop(albedo, frame["window"], frame["size"])
    shape = tuple(frame["grid"].shape)
    if frame["size"] != shape:
        albedo = F.interpolate(albedo, size=shape, mode="trilinear", align_corners=False)
    return albedo[0]


def cropped_fit(frame: dict) -> bool:
    """Whether a fit step on ``frame`` (``prepare_frame``) works on its crop window alone: the albedo, the
    layer's render (``render_views``' ``window``) and the smoothness term. Outside the window the albedo
    only repeats the window's faces, where the density is at most ``OCCUPIED_DENSITY``."""
    return frame["window"] is not None and tuple(frame["size"]) == tuple(frame["grid"].shape)


def solid_texture_start(style: np.ndarray, texels: tuple, strength: float, seed: int = 0):
    """A look's texture start ``(3, *texels)``: a solid texture of ``style`` (``mistyle.solid_texture``)
    over the box, each channel centred on its mean and scaled by ``strength`` (logits of the head)."""
    import torch

    from ..solid_texture import SolidTextureSettings, solid_texture_of, texture_in_box

    solid = solid_texture_of(style, SolidTextureSettings(seed=seed))
    values = texture_in_box(solid, texels)
    values = strength * (values - values.reshape(-1, 3).mean(axis=0))
    return torch.from_numpy(np.ascontiguousarray(values.transpose(3, 0, 1, 2)))


def thumbnail_of(style: np.ndarray, side: int = THUMBNAIL_SIDE) -> np.ndarray:
    """``style (H, W, 3)`` in [0, 1] as uint8, its longest side at most ``side`` pixels."""
    from PIL import Image

    image = Image.fromarray((np.clip(style, 0, 1) * 255 + 0.5).astype(np.uint8))
    scale = side / max(image.size)
    if scale < 1:
        image = image.resize(
            (max(1, round(image.size[0] * scale)), max(1, round(image.size[1] * scale))), Image.LANCZOS
        )
    return np.asarray(image, dtype=np.uint8).copy()
