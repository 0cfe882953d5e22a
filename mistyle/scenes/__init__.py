"""Scene parts shared by the fast layer and the path tracer: box, cameras, medium, environment."""

from .box import MediumBox
from .builder import constant_environment, layer_scene, pathtraced_scene, split_views
from .cameras import CameraPath, View, batch_sensor_dict, sensor_dict
from .medium import DEFAULT_DENSITY_SCALE, PreparedDensity, prepare_density

__all__ = [
    "CameraPath", "DEFAULT_DENSITY_SCALE", "MediumBox", "PreparedDensity", "View", "batch_sensor_dict",
    "constant_environment", "layer_scene", "pathtraced_scene", "prepare_density", "sensor_dict", "split_views",
]
