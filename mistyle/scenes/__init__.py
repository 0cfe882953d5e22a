"""What the fast layer and the path tracer share: the medium box, cameras, the medium, lights,
and the one path-traced scene builder (and its export as files, ``export``). Imports ``backend``,
``conventions``, ``volume`` and ``io`` only."""

from .box import MediumBox
from .cameras import CameraPath, View, batch_sensor_dict, sensor_dict, split_views
from .lights import LightSpec, constant_environment
from .medium import (
    albedo_parameter,
    heterogeneous_medium,
    medium_cube,
    validate_density_scale,
)
from .pathtraced import pathtraced_scene, update_pathtraced_scene

__all__ = [
    "CameraPath",
    "LightSpec",
    "MediumBox",
    "View",
    "albedo_parameter",
    "batch_sensor_dict",
    "constant_environment",
    "heterogeneous_medium",
    "medium_cube",
    "pathtraced_scene",
    "sensor_dict",
    "split_views",
    "update_pathtraced_scene",
    "validate_density_scale",
]
