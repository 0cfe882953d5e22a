"""Scene dictionaries for the fast layer and for the path tracer, built from the same parts.

Both scenes take the same density, ``density_scale``, medium box, environment and cameras, so the
same inputs give comparable images (``tests/test_layer_vs_pathtracer.py`` checks that they agree).
"""

from __future__ import annotations

import numpy as np

from ..backend import active_variant
from ..integrators import DEFAULT_SCHEME
from ..volume import validate_albedo
from .box import MediumBox
from .cameras import View, batch_sensor_dict
from .medium import PreparedDensity, validate_density_scale

# The training light. Single scattering under a unit environment cannot exceed a radiance of about
# 0.7 even for white albedo, which the tone curve shows as mid grey, so bright styles were out of
# reach; measured with experiments/optimize_albedo.py --quick (held-out SWD after 60 steps,
# 3 styles): Le = 2: 0.224, 4: 0.178, 8: 0.162, 16: 0.167. Le = 8 puts white albedo at ~0.93 on screen.
DEFAULT_ENV_RADIANCE = 8.0


def constant_environment(radiance: float = DEFAULT_ENV_RADIANCE) -> dict:
    """The training light: a constant, white environment of the given radiance."""
    return {"type": "constant", "radiance": {"type": "rgb", "value": float(radiance)}}


def _transform(matrix: np.ndarray):
    mi = active_variant()

    return mi.ScalarTransform4f(matrix.tolist())


def layer_scene(
    prepared: PreparedDensity,
    albedo: np.ndarray,
    views: list[View],
    width: int,
    height: int,
    steps: int = 64,
    scheme: str = DEFAULT_SCHEME,
    radiance: float = DEFAULT_ENV_RADIANCE,
) -> dict:
    """Scene rendered by the fast layer: all ``views`` side by side in one batch film."""
    mi = active_variant()

    albedo = validate_albedo(albedo, prepared.shape)
    box = prepared.box
    return {
        "type": "scene",
        "integrator": {
            "type": "mistyle_single_scatter",
            "sigma_t": mi.TensorXf(prepared.sigma_t[..., None]),
            "ls": mi.TensorXf(prepared.ls[..., None]),
            "albedo": mi.TensorXf(albedo),
            "bbox_min": mi.ScalarPoint3f(box.bbox_min),
            "bbox_max": mi.ScalarPoint3f(box.bbox_max),
            "steps": int(steps),
            "scheme": scheme,
        },
        "sensor": _with_sampler(batch_sensor_dict(views, width, height), spp=1),
        "environment": constant_environment(radiance),
    }


def heterogeneous_medium(density: np.ndarray, density_scale: float, albedo: np.ndarray) -> dict:
    """Mitsuba ``heterogeneous`` medium filling the medium box, trilinear grids, isotropic phase."""
    mi = active_variant()

    box = MediumBox(density.shape)
    to_world = _transform(box.unit_to_world_matrix())
    return {
        "type": "heterogeneous",
        "sigma_t": {
            "type": "gridvolume",
            "grid": mi.VolumeGrid(np.ascontiguousarray(density, dtype=np.float32)),
            "to_world": to_world,
            "filter_type": "trilinear",
        },
        "scale": validate_density_scale(density_scale),
        "albedo": {
            "type": "gridvolume",
            "grid": mi.VolumeGrid(validate_albedo(albedo, density.shape)),
            "to_world": to_world,
            "filter_type": "trilinear",
        },
        "phase": {"type": "isotropic"},
    }


def pathtraced_scene(
    density: np.ndarray,
    density_scale: float,
    albedo: np.ndarray,
    views: list[View],
    width: int,
    height: int,
    spp: int = 64,
    max_depth: int = -1,
    radiance: float = DEFAULT_ENV_RADIANCE,
    seed: int = 0,
) -> dict:
    """Path-traced comparison scene: ``volpath`` through a null-BSDF cube holding the medium.

    ``max_depth=2`` is single scattering (the layer's model); ``-1`` is full multiple scattering.
    Emitters are hidden, so pixels that see no medium are black as in the layer.
    """
    return {
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": int(max_depth), "hide_emitters": True},
        "sensor": _with_sampler(batch_sensor_dict(views, width, height), spp=spp, seed=seed),
        "environment": constant_environment(radiance),
        "medium_box": medium_cube(density, density_scale, albedo),
    }


def medium_cube(density: np.ndarray, density_scale: float, albedo: np.ndarray, bsdf: dict | None = None) -> dict:
    """The cube spanning the medium box with the heterogeneous medium inside; ``bsdf`` default ``null``."""
    return {
        "type": "cube",
        "to_world": _transform(MediumBox(density.shape).cube_to_world_matrix()),
        "bsdf": bsdf or {"type": "null"},
        "interior": heterogeneous_medium(density, density_scale, albedo),
    }


def _with_sampler(sensor: dict, spp: int, seed: int = 0) -> dict:
    if spp < 1:
        raise ValueError(f"spp must be >= 1, got {spp}.")
    sensor["sampler"] = {"type": "independent", "sample_count": int(spp), "seed": int(seed)}
    return sensor


def split_views(image, view_count: int) -> np.ndarray:
    """Batch film ``(H, V*W, 3)`` -> per-view images ``(V, H, W, 3)``."""
    array = np.asarray(image, dtype=np.float32)
    height, total_width, channels = array.shape
    if total_width % view_count:
        raise ValueError(f"Film width {total_width} is not a multiple of {view_count} views.")
    return array.reshape(height, view_count, total_width // view_count, channels).transpose(1, 0, 2, 3).copy()
