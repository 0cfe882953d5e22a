"""The heterogeneous medium in its box, as the path tracer sees it (Mitsuba ``heterogeneous``)."""

from __future__ import annotations

import numpy as np

from ..backend import require_variant
from ..conventions import MAX_DENSITY_SCALE
from ..volume import validate_albedo
from .box import MediumBox


def validate_density_scale(density_scale, name: str = "density_scale") -> float:
    """``density_scale`` as a float; ``ValueError`` naming ``name`` unless in ``(0, MAX_DENSITY_SCALE]``."""
    try:
        scale = float(density_scale)
    except (TypeError, ValueError):
        scale = float("nan")
    if not np.isfinite(scale) or not 0 < scale <= MAX_DENSITY_SCALE:
        raise ValueError(f"{name} must lie in (0, {MAX_DENSITY_SCALE:g}], got {density_scale!r}.")
    return scale


def heterogeneous_medium(
    density: np.ndarray, density_scale: float, albedo, unit_to_world: np.ndarray | None = None
) -> dict:
    """Mitsuba ``heterogeneous`` medium, trilinear grids, isotropic phase.

    Its grids fill the medium box of ``density``, or the box onto which the 4x4 ``unit_to_world``
    maps the unit cube. ``albedo``: ``(Z, Y, X, 3)`` in [0, 1], or an albedo ``gridvolume`` already
    loaded (``mi.load_dict(grid_volume(...))``) that several media share (``scenes.bricks``).
    """
    mi = require_variant()
    if unit_to_world is None:
        unit_to_world = MediumBox(density.shape).unit_to_world_matrix()
    if not isinstance(albedo, mi.Volume):
        albedo = grid_volume(validate_albedo(albedo, density.shape), unit_to_world)
    return {
        "type": "heterogeneous",
        "sigma_t": grid_volume(np.ascontiguousarray(density, dtype=np.float32), unit_to_world),
        "scale": validate_density_scale(density_scale),
        "albedo": albedo,
        "phase": {"type": "isotropic"},
    }


def grid_volume(values: np.ndarray, unit_to_world: np.ndarray) -> dict:
    """A trilinear Mitsuba ``gridvolume`` of ``values`` (``(Z, Y, X)`` or ``(Z, Y, X, C)`` float32)
    on the box onto which the 4x4 ``unit_to_world`` maps the unit cube."""
    mi = require_variant()
    return {
        "type": "gridvolume",
        "grid": mi.VolumeGrid(np.ascontiguousarray(values, dtype=np.float32)),
        "to_world": mi.ScalarTransform4f(np.asarray(unit_to_world, dtype=np.float64).tolist()),
        "filter_type": "trilinear",
    }


def medium_cube(density: np.ndarray, density_scale: float, albedo: np.ndarray, bsdf: dict | None = None) -> dict:
    """The cube spanning the medium box with the heterogeneous medium inside; ``bsdf`` default ``null``."""
    mi = require_variant()
    return {
        "type": "cube",
        "to_world": mi.ScalarTransform4f(MediumBox(density.shape).cube_to_world_matrix().tolist()),
        "bsdf": bsdf or {"type": "null"},
        "interior": heterogeneous_medium(density, density_scale, albedo),
    }


ALBEDO_PARAMETER_SUFFIX = "interior_medium.albedo.data"
"""How ``mi.traverse`` names the medium's albedo grid in a scene built with ``medium_cube``."""


def albedo_parameter(params) -> str:
    """The key of the medium's albedo grid among a loaded scene's parameters (``mi.traverse``)."""
    return next(key for key in params.keys() if key.endswith(ALBEDO_PARAMETER_SUFFIX))


def update_medium(params, density: np.ndarray, albedo: np.ndarray) -> None:
    """Set a new frame's grids in the parameters (``mi.traverse(scene)``, not yet updated) of a scene
    holding one ``heterogeneous_medium`` of a grid of the same shape (``medium_cube`` or a coat mesh):
    the grids and their majorant are data to the kernel, so the scene renders the new frame without
    compiling anew. ``density``: ``(Z, Y, X)``; ``albedo``: ``(Z, Y, X, 3)`` in [0, 1]."""
    mi = require_variant()
    albedo_key = albedo_parameter(params)
    params[albedo_key.replace(".albedo.data", ".sigma_t.data")] = mi.TensorXf(
        np.ascontiguousarray(density, dtype=np.float32)[..., None]
    )
    params[albedo_key] = mi.TensorXf(validate_albedo(albedo, density.shape))
