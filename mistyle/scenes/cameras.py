"""Cameras: single views, the training orbit (camera path) and their Mitsuba sensors.

The training cameras lie on one predefined orbit around the medium box (+y up), as in the paper's
"predefined camera path"; each training update samples views on it. Final renders use the same
orbit for turntables, so a stylized volume is judged from the viewpoints it was trained on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..backend import require_variant
from ..conventions import HELD_OUT_VIEW, MIN_CAMERA_DISTANCE, ORBIT_DISTANCE

MAX_CAMERA_DISTANCE = 100.0


def validate_camera_distance(distance, name: str = "camera distance") -> float:
    """An orbit radius outside the medium box, ``(MIN_CAMERA_DISTANCE, MAX_CAMERA_DISTANCE]``."""
    if not (np.isfinite(distance) and MIN_CAMERA_DISTANCE < distance <= MAX_CAMERA_DISTANCE):
        raise ValueError(
            f"{name} must lie in ({MIN_CAMERA_DISTANCE}, {MAX_CAMERA_DISTANCE:g}] "
            f"(the medium box's longest side is 1), got {distance}."
        )
    return float(distance)


def validate_orbit_position(u, name: str = "view") -> float:
    """A position on the orbit as ``--view`` and ``mistyle.render(view=u)`` take it, in ``[0, 1)``."""
    try:
        position = float(u)
    except (TypeError, ValueError):
        position = float("nan")
    if not (np.isfinite(position) and 0.0 <= position < 1.0):
        raise ValueError(f"{name} is an orbit position in [0, 1), got {u!r}.")
    return position


@dataclass(frozen=True)
class View:
    """A pinhole camera looking at ``target`` from ``origin``; ``fov_deg`` spans the image width."""

    origin: tuple[float, float, float]
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov_deg: float = 40.0

    def __post_init__(self):
        for name in ("origin", "target", "up"):
            value = np.asarray(getattr(self, name), dtype=np.float64)
            if value.shape != (3,) or not np.all(np.isfinite(value)):
                raise ValueError(f"View.{name} must be 3 finite numbers, got {getattr(self, name)!r}.")
            object.__setattr__(self, name, tuple(float(v) for v in value))
        if not 0.0 < self.fov_deg < 180.0:
            raise ValueError(f"View.fov_deg must lie in (0, 180), got {self.fov_deg}.")
        forward = np.subtract(self.target, self.origin)
        if np.linalg.norm(forward) == 0 or np.linalg.norm(np.cross(forward, self.up)) < 1e-9:
            raise ValueError(f"View needs origin != target and an up vector not parallel to the view: {self}.")


@dataclass(frozen=True)
class CameraPath:
    """An orbit around the +y axis at ``distance`` from the origin.

    Position ``u`` in ``[0, 1)`` sets the azimuth ``2 pi u``; the elevation oscillates around
    ``elevation_deg`` by ``elevation_wobble_deg`` twice per turn, so views see the medium from
    above and below as well as from the side.
    """

    distance: float = ORBIT_DISTANCE
    elevation_deg: float = 10.0
    elevation_wobble_deg: float = 20.0
    fov_deg: float = 40.0

    def __post_init__(self):
        validate_camera_distance(self.distance, "CameraPath.distance")

    def view(self, u: float) -> View:
        azimuth = 2.0 * math.pi * u
        elevation = math.radians(self.elevation_deg + self.elevation_wobble_deg * math.sin(4.0 * math.pi * u))
        origin = self.distance * np.array(
            [math.cos(elevation) * math.sin(azimuth), math.sin(elevation), math.cos(elevation) * math.cos(azimuth)]
        )
        return View(origin=tuple(origin), fov_deg=self.fov_deg)

    def sample(self, count: int, rng: np.random.Generator) -> list[View]:
        """``count`` views at independent uniform positions on the orbit."""
        return [self.view(u) for u in rng.random(count)]

    def sample_stratified(self, count: int, rng: np.random.Generator) -> list[View]:
        """``count`` views evenly spaced around the orbit from one uniform random offset: each is uniform
        on the orbit, as ``sample``'s are, and together they never bunch on one side."""
        offset = rng.random()
        return [self.view((offset + i) / count % 1.0) for i in range(count)]

    def turntable(self, frames: int, offset: float = 0.0) -> list[View]:
        """``frames`` evenly spaced views, one full turn."""
        return [self.view(offset + i / frames) for i in range(frames)]

    def held_out(self, count: int = 1) -> list[View]:
        """The evaluation views: ``count`` evenly spaced, starting at ``conventions.HELD_OUT_VIEW``."""
        return self.turntable(count, offset=HELD_OUT_VIEW)


def sensor_dict(view: View, width: int, height: int, spp: int = 1, seed: int = 0) -> dict:
    """Mitsuba ``perspective`` sensor for ``view`` with a box-filtered linear RGB film."""
    mi = require_variant()

    if width < 1 or height < 1:
        raise ValueError(f"Image size must be at least 1x1, got {width}x{height}.")
    return {
        "type": "perspective",
        "fov": view.fov_deg,
        "fov_axis": "x",
        "to_world": mi.ScalarTransform4f().look_at(origin=view.origin, target=view.target, up=view.up),
        "film": film_dict(width, height),
        "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
    }


def update_sensors(params, views: list[View]) -> None:
    """Point the sensors ``sensor000``, ``sensor001``, ... of a loaded scene's parameters
    (``mi.traverse(scene)``, not yet updated) at ``views``, as ``sensor_dict`` would build them: a
    camera's placement and field of view are data to the kernel, so a scene kept for the next frame
    renders a new view without compiling anew."""
    mi = require_variant()
    for index, view in enumerate(views):
        name = f"sensor{index:03d}"
        params[f"{name}.to_world"] = mi.Transform4f(
            mi.ScalarTransform4f().look_at(origin=view.origin, target=view.target, up=view.up)
        )
        params[f"{name}.x_fov"] = mi.Float(view.fov_deg)


def film_dict(width: int, height: int) -> dict:
    return {
        "type": "hdrfilm",
        "width": int(width),
        "height": int(height),
        "pixel_format": "rgb",
        "rfilter": {"type": "box"},
    }


def batch_sensor_dict(views: list[View], width: int, height: int) -> dict:
    """One Mitsuba ``batch`` sensor that renders all ``views`` side by side in one launch.

    The film is ``(height, len(views) * width)``; view ``v`` occupies columns
    ``[v * width, (v + 1) * width)``.
    """
    if not views:
        raise ValueError("At least one view is needed.")
    sensor = {"type": "batch", "film": film_dict(width * len(views), height)}
    for index, view in enumerate(views):
        sub = sensor_dict(view, width, height)
        sub.pop("sampler")
        sensor[f"view{index:03d}"] = sub
    return sensor


def split_views(image, view_count: int) -> np.ndarray:
    """A ``batch_sensor_dict`` film ``(H, V*W, 3)`` -> per-view images ``(V, H, W, 3)``."""
    array = np.asarray(image, dtype=np.float32)
    height, total_width, channels = array.shape
    if total_width % view_count:
        raise ValueError(f"Film width {total_width} is not a multiple of {view_count} views.")
    return array.reshape(height, view_count, total_width // view_count, channels).transpose(1, 0, 2, 3).copy()
