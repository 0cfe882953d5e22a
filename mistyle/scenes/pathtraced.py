"""The one path-traced scene: the medium in its box (or a coat mesh), a light, and cameras.

``volpath`` (Mitsuba's heterogeneous-medium path tracer) renders the medium of
``medium.heterogeneous_medium``. The boundary is invisible (``null`` BSDF) or a smooth dielectric
coat (``dielectric``, for the translucent-solid look of marble or jade): the box, or a closed mesh
placed in the box (for voxelized meshes, so the coat follows the surface). Emitters are hidden,
so pixels that see no medium are black, as in the fast layer.

The comparison with the fast layer uses the same builder with the training light, ``max_depth=2``
(single scattering, the layer's model) and ``batch=True`` (all views side by side in one film, as
the layer renders them); ``tests/test_layer_vs_pathtracer.py`` checks that the two agree.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .bricks import DEFAULT_LEVELS, bricked_media, update_bricked_media
from .cameras import View, batch_sensor_dict, sensor_dict, update_sensors
from .lights import LightSpec
from .medium import heterogeneous_medium, medium_cube, update_medium

PATH_TRACERS = ("volpath", "prbvolpath")
MAX_DEPTH_LIMIT = 1024
COAT_IOR_RANGE = (1.0, 4.0)  # open interval


def validate_max_depth(max_depth: int, name: str = "max_depth") -> int:
    """``-1`` (unlimited) or a path length in ``[1, MAX_DEPTH_LIMIT]``; ``ValueError`` naming ``name``."""
    if not (max_depth == -1 or 1 <= max_depth <= MAX_DEPTH_LIMIT):
        raise ValueError(f"{name} must be -1 (unlimited) or lie in [1, {MAX_DEPTH_LIMIT}], got {max_depth}.")
    return int(max_depth)


def validate_coat_ior(coat_ior, name: str = "coat_ior") -> float | None:
    """``None`` (no coat) or an index of refraction in ``COAT_IOR_RANGE``; ``ValueError`` naming ``name``."""
    low, high = COAT_IOR_RANGE
    if coat_ior is not None and not (np.isfinite(coat_ior) and low < coat_ior < high):
        raise ValueError(f"{name} needs an index of refraction in ({low:g}, {high:g}), e.g. 1.5; got {coat_ior}.")
    return coat_ior


def pathtraced_scene(
    density: np.ndarray,
    albedo: np.ndarray,
    views: list[View],
    *,
    res: int | tuple[int, int],
    density_scale: float,
    spp: int = 64,
    max_depth: int = -1,
    light: LightSpec | None = None,
    coat_ior: float | None = None,
    coat_mesh: str | Path | None = None,
    seed: int = 0,
    batch: bool = False,
    integrator: str = "volpath",
    bricks: int = 0,
    brick_split: tuple | None = None,
) -> dict:
    """A Mitsuba scene dictionary for ``mi.load_dict``.

    Args:
        density: ``(Z, Y, X)``; albedo: ``(Z, Y, X, 3)`` in [0, 1].
        views: the cameras; with ``batch=False`` one sensor each (``mi.render(scene, sensor=i)``, view
            ``i`` seeded ``seed + i``), with ``batch=True`` one ``batch`` sensor whose film holds all
            views side by side (``cameras.split_views``).
        res: image side, or ``(height, width)``, per view.
        max_depth: ``-1`` full multiple scattering; ``2`` single scattering.
        coat_ior: index of refraction of a smooth dielectric boundary; ``None``: no coat.
        coat_mesh: a closed ``.ply`` already placed in the medium box (see
            ``mistyle.data.mesh.fit_to_box``), used as the coat instead of the box.
        integrator: ``volpath``, or ``prbvolpath`` for gradients with respect to the albedo.
        bricks: ``0`` one medium in the box; ``n`` the box cut into bricks of ``n`` voxels with
            majorants of their own (``scenes.bricks``: the same image in expectation, less time on
            sparse volumes). Only without a coat and with ``volpath``.
        brick_split: ``bricks.brick_levels(density, bricks, DEFAULT_LEVELS)`` when the caller has it.
    """
    height, width = (res, res) if np.isscalar(res) else (int(res[0]), int(res[1]))
    if spp < 1:
        raise ValueError(f"spp must be >= 1, got {spp}.")
    validate_max_depth(max_depth)
    validate_coat_ior(coat_ior)
    if integrator not in PATH_TRACERS:
        raise ValueError(f"Unknown path tracer {integrator!r}; use one of {PATH_TRACERS}.")
    bsdf = {"type": "null"} if coat_ior is None else {"type": "dielectric", "int_ior": float(coat_ior), "ext_ior": 1.0}
    if bricks and (coat_ior is not None or integrator != "volpath"):
        raise ValueError(
            "bricks work with volpath and no coat only: a coat is an optical boundary on the box, and "
            "prbvolpath differentiates one albedo grid; use bricks=0."
        )
    if bricks:
        boundary = bricked_media(density, density_scale, albedo, bricks, split=brick_split)
    elif coat_mesh is not None and coat_ior is not None:
        boundary = {
            "medium_box": {
                "type": "ply",
                "filename": str(coat_mesh),
                "bsdf": bsdf,
                "interior": heterogeneous_medium(density, density_scale, albedo),
            }
        }
    else:
        boundary = {"medium_box": medium_cube(density, density_scale, albedo, bsdf)}
    scene = {
        "type": "scene",
        "integrator": {"type": integrator, "max_depth": int(max_depth), "hide_emitters": True},
        **boundary,
        **(LightSpec() if light is None else light).emitters(),
    }
    if batch:
        sensor = batch_sensor_dict(views, width, height)
        sensor["sampler"] = {"type": "independent", "sample_count": int(spp), "seed": int(seed)}
        scene["sensor"] = sensor
    else:
        for index, view in enumerate(views):
            scene[f"sensor{index:03d}"] = sensor_dict(view, width, height, spp=spp, seed=seed + index)
    return scene


def update_pathtraced_scene(
    params, density: np.ndarray, albedo: np.ndarray, views: list[View] | None, *, bricks: int = 0, brick_split=None
) -> None:
    """Set a new frame in the parameters (``mi.traverse(scene)``; the caller then calls
    ``params.update()``) of a loaded ``pathtraced_scene`` (``batch=False``) of the same structure: the
    grid's shape, the number of views, every other setting, and with ``bricks`` the same
    ``bricks.present_levels``. The scene then renders as one built anew from these arguments, with
    the kernels it has already compiled: what changes is data (grids, majorants, face meshes,
    cameras), never a literal in the kernel.

    Args:
        density: ``(Z, Y, X)``; albedo: ``(Z, Y, X, 3)`` in [0, 1]; views: one per sensor, or ``None``
            to leave the cameras as they are.
        bricks, brick_split: as ``pathtraced_scene``.
    """
    if bricks:
        update_bricked_media(params, density, albedo, bricks, DEFAULT_LEVELS, split=brick_split)
    else:
        update_medium(params, density, albedo)
    if views is not None:
        update_sensors(params, views)
