"""Volume arrays: the one validation of densities and albedo grids.

Every volume that enters mistyle passes through ``validate_density`` or ``validate_albedo``, which
return float32 C-contiguous arrays in the grid convention of ``mistyle.scenes.box`` or raise a
``ValueError`` that names the problem. Files are read and written by ``mistyle.files``.
"""

from __future__ import annotations

import numpy as np

from .conventions import MAX_DENSITY, MAX_EXTINCTION


def validate_density(density, name: str = "density") -> np.ndarray:
    """Check a density grid and return it as float32 C-contiguous ``(Z, Y, X)``.

    Raises:
        ValueError: wrong rank, zero size, non-finite or negative values.
    """
    array = np.asarray(density)
    if array.ndim == 4 and array.shape[-1] == 1:
        array = array[..., 0]
    if array.ndim == 4 and array.shape[-1] in (2, 3, 4):
        raise ValueError(
            f"{name} holds {array.shape[-1]} values a voxel (shape {array.shape}): a vector or colour grid, not "
            "a density. Choose the file's density grid (--grid NAME; mistyle-vdb FILE lists them)."
        )
    if array.ndim != 3:
        raise ValueError(f"{name} must be a 3D array (Z, Y, X), got shape {array.shape}.")
    if array.size == 0:
        raise ValueError(f"{name} is empty (shape {array.shape}); every axis needs at least one voxel.")
    if not np.issubdtype(array.dtype, np.number) or np.iscomplexobj(array):
        raise ValueError(f"{name} must hold real numbers, got dtype {array.dtype}.")
    if array.dtype.kind == "f" and array.dtype.itemsize > 4:
        _check_float32_range(array, name)
    array = np.ascontiguousarray(array, dtype=np.float32)
    bad = ~np.isfinite(array)
    if bad.any():
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(
            f"{name} holds {int(bad.sum())} NaN/inf values (first at [z, y, x] = {where}); "
            "clean the volume, e.g. np.nan_to_num(density, nan=0.0, posinf=0.0)."
        )
    if array.max(initial=0.0) > MAX_DENSITY:
        raise ValueError(
            f"{name} holds values up to {float(array.max()):.4g}; mistyle takes densities up to {MAX_DENSITY:g}. "
            "Normalise the volume (e.g. density / density.max()) and set the extinction with --density-scale."
        )
    if (array < 0).any():
        raise ValueError(
            f"{name} holds negative values (min {float(array.min()):.4g}); densities must be >= 0, "
            "e.g. np.clip(density, 0, None)."
        )
    return array


def _check_float32_range(array: np.ndarray, name: str) -> None:
    """A wider float grid's finite values beyond float32's range would turn into inf when cast; say so
    (with the largest) rather than report them as NaN/inf values the file does not hold."""
    limit = float(np.finfo(np.float32).max)
    beyond = (array > limit) | (array < -limit)
    beyond &= np.isfinite(array)
    if beyond.any():
        finite = np.isfinite(array)
        largest = max(float(array.max(where=finite, initial=0.0)), -float(array.min(where=finite, initial=0.0)))
        raise ValueError(
            f"{name} holds {int(beyond.sum())} values beyond float32's range (up to {largest:.4g}; float32 ends "
            f"at {limit:.4g}), and mistyle takes densities up to {MAX_DENSITY:g}. Normalise the volume (e.g. "
            "density / density.max()) and set the extinction with --density-scale."
        )


def validate_extinction(density, density_scale: float, name: str = "density") -> float:
    """The largest extinction ``max(density) * density_scale`` (per unit of the box's longest side) of a
    checked density grid; ``ValueError`` above ``MAX_EXTINCTION``, where a path-traced render's time, which
    grows with it, is out of bounds (``conventions.MAX_EXTINCTION``) and the medium looks no different."""
    peak = float(np.max(density, initial=0.0))
    extinction = peak * float(density_scale)
    if not extinction <= MAX_EXTINCTION:
        raise ValueError(
            f"{name} holds densities up to {peak:.4g}, which at density scale {float(density_scale):g} is an "
            f"extinction of {extinction:.4g} per box length; mistyle renders extinctions up to {MAX_EXTINCTION:g} "
            "(a render's time grows with it, and denser media look the same). Divide the density (e.g. density / "
            f"density.max()) or lower --density-scale so that max density x scale <= {MAX_EXTINCTION:g}."
        )
    return extinction


def box_of(mask: np.ndarray) -> tuple[slice, ...] | None:
    """The slices of the bounding box of ``mask``'s true voxels (any number of axes), None when there
    are none. From each axis's projection: no index array of the voxels themselves."""
    mask = np.asarray(mask, dtype=bool)
    box = []
    for axis in range(mask.ndim):
        present = np.flatnonzero(mask.any(axis=tuple(a for a in range(mask.ndim) if a != axis)))
        if len(present) == 0:
            return None
        box.append(slice(int(present[0]), int(present[-1]) + 1))
    return tuple(box)


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
