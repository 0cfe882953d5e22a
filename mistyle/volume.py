"""Volume arrays: validation and Mitsuba ``.vol`` / ``.npy`` files.

Every volume that enters mistyle passes through ``validate_density`` or ``validate_albedo``, which
return float32 C-contiguous arrays in the grid convention of ``mistyle.scenes.box`` or raise a
``ValueError`` that names the problem.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np

from .io import atomic_write_bytes


def validate_density(density, name: str = "density") -> np.ndarray:
    """Check a density grid and return it as float32 C-contiguous ``(Z, Y, X)``.

    Raises:
        ValueError: wrong rank, zero size, non-finite or negative values.
    """
    array = np.asarray(density)
    if array.ndim == 4 and array.shape[-1] == 1:
        array = array[..., 0]
    if array.ndim != 3:
        raise ValueError(f"{name} must be a 3D array (Z, Y, X), got shape {array.shape}.")
    if array.size == 0:
        raise ValueError(f"{name} is empty (shape {array.shape}); every axis needs at least one voxel.")
    if not np.issubdtype(array.dtype, np.number) or np.iscomplexobj(array):
        raise ValueError(f"{name} must hold real numbers, got dtype {array.dtype}.")
    array = np.ascontiguousarray(array, dtype=np.float32)
    bad = ~np.isfinite(array)
    if bad.any():
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(
            f"{name} holds {int(bad.sum())} NaN/inf values (first at [z, y, x] = {where}); "
            "clean the volume, e.g. np.nan_to_num(density, nan=0.0, posinf=0.0)."
        )
    if (array < 0).any():
        raise ValueError(
            f"{name} holds negative values (min {float(array.min()):.4g}); densities must be >= 0, "
            "e.g. np.clip(density, 0, None)."
        )
    return array


def validate_albedo(albedo, shape_zyx: tuple[int, int, int] | None = None, name: str = "albedo") -> np.ndarray:
    """Check an RGB albedo grid ``(Z, Y, X, 3)`` in [0, 1] and return it as float32 C-contiguous."""
    array = np.asarray(albedo)
    if array.ndim != 4 or array.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (Z, Y, X, 3), got {array.shape}.")
    if shape_zyx is not None and tuple(array.shape[:3]) != tuple(shape_zyx):
        raise ValueError(f"{name} grid {array.shape[:3]} does not match the density grid {tuple(shape_zyx)}.")
    array = np.ascontiguousarray(array, dtype=np.float32)
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} holds NaN/inf values.")
    if array.min() < 0 or array.max() > 1:
        raise ValueError(f"{name} must lie in [0, 1], got [{array.min():.4g}, {array.max():.4g}].")
    return array


# --- Mitsuba's binary grid format: b"VOL", version 3, encoding 1 (float32), then
# --- X, Y, Z, channels (int32), the bounding box (6 x float32) and the data in [z, y, x, c] order.
_VOL_HEADER = struct.Struct("<3sBiiiii6f")


def write_vol(path, grid: np.ndarray, bbox_min=(0.0, 0.0, 0.0), bbox_max=(1.0, 1.0, 1.0)) -> Path:
    """Write a ``(Z, Y, X)`` or ``(Z, Y, X, C)`` grid as a Mitsuba ``.vol`` file, atomically."""
    data = np.asarray(grid, dtype=np.float32)
    if data.ndim == 3:
        data = data[..., None]
    if data.ndim != 4:
        raise ValueError(f".vol grids must be (Z, Y, X) or (Z, Y, X, C), got shape {data.shape}.")
    z, y, x, c = data.shape
    header = _VOL_HEADER.pack(b"VOL", 3, 1, x, y, z, c, *bbox_min, *bbox_max)
    return atomic_write_bytes(path, header + np.ascontiguousarray(data).tobytes())


def read_vol(path) -> np.ndarray:
    """Read a float32 Mitsuba ``.vol`` file; returns ``(Z, Y, X)`` for one channel, else ``(Z, Y, X, C)``."""
    raw = Path(path).read_bytes()
    if len(raw) < _VOL_HEADER.size or raw[:3] != b"VOL":
        raise ValueError(f"{path} is not a Mitsuba .vol file (missing the 'VOL' header).")
    magic, version, encoding, x, y, z, c, *_bbox = _VOL_HEADER.unpack_from(raw)
    if version != 3 or encoding != 1:
        raise ValueError(f"{path}: only .vol version 3 with float32 data is supported (got version {version}, encoding {encoding}).")
    count = x * y * z * c
    if len(raw) - _VOL_HEADER.size != 4 * count:
        raise ValueError(f"{path}: header says {x}x{y}x{z}x{c} floats but the file holds {(len(raw) - _VOL_HEADER.size) // 4}.")
    data = np.frombuffer(raw, dtype="<f4", offset=_VOL_HEADER.size, count=count).reshape(z, y, x, c)
    data = np.array(data, dtype=np.float32)
    return data[..., 0] if c == 1 else data


def load_density(path) -> np.ndarray:
    """Load a density grid from ``.vol`` or ``.npy`` and validate it."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"Density file {path} does not exist.")
    suffix = path.suffix.lower()
    if suffix == ".vol":
        array = read_vol(path)
    elif suffix == ".npy":
        array = np.load(path, allow_pickle=False)
    else:
        raise ValueError(f"Unsupported density file {path}: use a Mitsuba .vol or a numpy .npy (Z, Y, X) grid.")
    return validate_density(array, name=os.fspath(path))
