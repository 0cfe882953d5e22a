"""The final path-traced scene: the stylized medium under a chosen light, optionally coated.

``volpath`` (Mitsuba's heterogeneous-medium path tracer, multiple scattering) renders the medium
box of ``builder.heterogeneous_medium``. The boundary is invisible (``null`` BSDF) or a smooth
dielectric coat (``dielectric``, for the translucent-solid look of marble or jade): the box, or
a closed mesh placed in the box (for voxelized meshes, so the coat follows the surface).

Lights (``LightSpec.parse``)::

    constant[:Le]             the training light: a white constant environment (default Le: training)
    envmap:<file.exr>[:scale] an environment map
    point:x,y,z[:intensity]   an isotropic point light (intensity in W/sr)
    area[:radiance]           a square area light above the medium, facing down
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..backend import active_variant
from .builder import (
    DEFAULT_ENV_RADIANCE,
    constant_environment,
    heterogeneous_medium,
    medium_cube,
)
from .cameras import View, sensor_dict


@dataclass(frozen=True)
class LightSpec:
    kind: str = "constant"  # constant | envmap | point | area
    value: float = DEFAULT_ENV_RADIANCE  # Le, envmap scale, point intensity or area radiance
    position: tuple[float, float, float] = (0.0, 2.0, 1.0)
    filename: str = ""

    @classmethod
    def parse(cls, text: str, default_radiance: float = DEFAULT_ENV_RADIANCE) -> LightSpec:
        kind, _, rest = text.partition(":")
        try:
            if kind == "constant":
                return cls("constant", float(rest) if rest else default_radiance)
            if kind == "envmap":
                filename, _, scale = rest.partition(":")
                if not filename or not Path(filename).is_file():
                    raise ValueError(f"the environment map {filename!r} does not exist")
                return cls("envmap", float(scale) if scale else 1.0, filename=filename)
            if kind == "point":
                where, _, intensity = rest.partition(":")
                position = tuple(float(v) for v in where.split(","))
                if len(position) != 3:
                    raise ValueError("a point light needs x,y,z")
                return cls("point", float(intensity) if intensity else 4.0 * default_radiance, position=position)
            if kind == "area":
                return cls("area", float(rest) if rest else default_radiance)
        except ValueError as error:
            raise ValueError(f"--light {text!r}: {error}. {_LIGHT_HELP}") from None
        raise ValueError(f"--light {text!r} is not a known light. {_LIGHT_HELP}")

    def emitters(self) -> dict:
        mi = active_variant()
        if self.kind == "constant":
            return {"environment": constant_environment(self.value)}
        if self.kind == "envmap":
            return {"environment": {"type": "envmap", "filename": self.filename, "scale": self.value}}
        if self.kind == "point":
            return {"light": {"type": "point", "position": list(self.position),
                              "intensity": {"type": "rgb", "value": self.value}}}
        # A 1.5 x 1.5 square 1.5 above the centre, emitting downwards (rectangle normals are +z).
        to_world = mi.ScalarTransform4f().translate([0.0, 1.5, 0.0]).rotate([1, 0, 0], 90).scale(0.75)
        return {"light": {"type": "rectangle", "to_world": to_world,
                          "emitter": {"type": "area", "radiance": {"type": "rgb", "value": self.value}}}}


_LIGHT_HELP = "Use constant[:Le], envmap:<file.exr>[:scale], point:x,y,z[:intensity] or area[:radiance]."


def final_scene(
    density: np.ndarray,
    density_scale: float,
    albedo: np.ndarray,
    views: list[View],
    width: int,
    height: int,
    spp: int = 64,
    max_depth: int = -1,
    light: LightSpec = LightSpec(),
    coat_ior: float | None = None,
    coat_mesh: str | Path | None = None,
    seed: int = 0,
) -> dict:
    """A scene with one sensor per view (``mi.render(scene, sensor=i)``).

    Args:
        density: ``(Z, Y, X)``; albedo: ``(Z, Y, X, 3)`` in [0, 1].
        coat_ior: index of refraction of a smooth dielectric boundary; ``None``: no coat.
        coat_mesh: a closed ``.ply`` already placed in the medium box (see
            ``mistyle.data.mesh.fit_to_box``), used as the coat instead of the box.
    """
    active_variant()

    if coat_ior is not None and not 1.0 < coat_ior < 4.0:
        raise ValueError(f"The coat's index of refraction must lie in (1, 4), e.g. 1.5; got {coat_ior}.")
    bsdf = {"type": "null"} if coat_ior is None else {"type": "dielectric", "int_ior": float(coat_ior), "ext_ior": 1.0}
    if coat_mesh is not None and coat_ior is not None:
        boundary = {"type": "ply", "filename": str(coat_mesh), "bsdf": bsdf,
                    "interior": heterogeneous_medium(density, density_scale, albedo)}
    else:
        boundary = medium_cube(density, density_scale, albedo, bsdf)
    scene = {
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": int(max_depth), "hide_emitters": True},
        "medium_box": boundary,
        **light.emitters(),
    }
    for index, view in enumerate(views):
        scene[f"sensor{index:03d}"] = sensor_dict(view, width, height, spp=spp, seed=seed + index)
    return scene

