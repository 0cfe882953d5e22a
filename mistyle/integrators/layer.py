"""The fast layer's scene: the ``mistyle_single_scatter`` integrator over a prepared density.

The layer and the path tracer (``mistyle.scenes.pathtraced_scene``) take the same medium box,
cameras and constant environment, so the same inputs give comparable images.
"""

from __future__ import annotations

import numpy as np

from ..backend import require_variant
from ..conventions import DEFAULT_ENV_RADIANCE, DEFAULT_LAYER_SCHEME, LAYER_MARCH_STEPS
from ..scenes.cameras import View, batch_sensor_dict
from ..scenes.lights import constant_environment
from ..volume import validate_albedo
from .prepared import PreparedDensity
from .registry import register


def layer_scene(
    prepared: PreparedDensity,
    albedo: np.ndarray,
    views: list[View],
    *,
    res: int | tuple[int, int],
    steps: int = LAYER_MARCH_STEPS,
    scheme: str = DEFAULT_LAYER_SCHEME,
    radiance: float = DEFAULT_ENV_RADIANCE,
    white: bool = False,
) -> dict:
    """Scene dictionary rendered by the fast layer: all ``views`` side by side in one batch film.

    ``res`` is the image side, or ``(height, width)``, per view. ``white``: the film also holds the
    views of a white albedo (the integrator's ``white`` AOVs, three channels after the RGB). Registers
    the integrator plugin for the active variant (which must have been chosen with
    ``mistyle.backend.use_variant``).
    """
    mi = require_variant()
    register()
    height, width = (res, res) if np.isscalar(res) else (int(res[0]), int(res[1]))
    albedo = validate_albedo(albedo, prepared.shape)
    box = prepared.box
    march_min, march_max = prepared.march_bounds
    sensor = batch_sensor_dict(views, width, height)
    sensor["sampler"] = {"type": "independent", "sample_count": 1}
    return {
        "type": "scene",
        "integrator": {
            "type": "mistyle_single_scatter",
            "sigma_t": mi.TensorXf(prepared.sigma_t[..., None]),
            "ls": mi.TensorXf(prepared.ls[..., None]),
            "albedo": mi.TensorXf(albedo),
            "bbox_min": mi.ScalarPoint3f(box.bbox_min),
            "bbox_max": mi.ScalarPoint3f(box.bbox_max),
            "march_min": mi.ScalarPoint3f(march_min),
            "march_max": mi.ScalarPoint3f(march_max),
            "steps": int(steps),
            "scheme": scheme,
            "white": bool(white),
        },
        "sensor": sensor,
        "environment": constant_environment(radiance),
    }
