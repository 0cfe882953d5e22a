"""Lights of the path-traced scene, and the constant environment the fast layer is trained under.

``LightSpec.parse`` reads the command-line form::

    constant[:Le]             the training light: a white constant environment (default Le: training)
    envmap:<file.exr>[:scale] an environment map
    point:x,y,z[:intensity]   an isotropic point light (intensity in W/sr)
    area[:radiance]           a square area light above the medium, facing down
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from ..backend import require_variant
from ..conventions import DEFAULT_ENV_RADIANCE, LIGHT_KINDS

LIGHT_HELP = "Use constant[:Le], envmap:<file.exr>[:scale], point:x,y,z[:intensity] or area[:radiance]."


def constant_environment(radiance: float = DEFAULT_ENV_RADIANCE) -> dict:
    """The training light: a constant, white environment of the given radiance."""
    return {"type": "constant", "radiance": {"type": "rgb", "value": float(radiance)}}


@dataclass(frozen=True)
class LightSpec:
    kind: str = "constant"  # one of conventions.LIGHT_KINDS
    value: float = DEFAULT_ENV_RADIANCE  # Le, envmap scale, point intensity or area radiance
    position: tuple[float, float, float] = (0.0, 2.0, 1.0)
    filename: str = ""

    def __post_init__(self):
        if self.kind not in LIGHT_KINDS:
            raise ValueError(f"Unknown light kind {self.kind!r}. {LIGHT_HELP}")
        if not (math.isfinite(self.value) and self.value > 0):
            raise ValueError(f"The {self.kind} light's strength must be a finite number > 0, got {self.value}.")
        if not all(math.isfinite(v) for v in self.position):
            raise ValueError(f"A light's position must be finite, got {self.position}.")

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
            raise ValueError(f"--light {text!r}: {str(error).rstrip('.')}. {LIGHT_HELP}") from None
        raise ValueError(f"--light {text!r} is not a known light. {LIGHT_HELP}")

    def emitters(self) -> dict:
        """Scene-dictionary entries for this light."""
        if self.kind == "constant":
            return {"environment": constant_environment(self.value)}
        if self.kind == "envmap":
            return {"environment": {"type": "envmap", "filename": self.filename, "scale": self.value}}
        if self.kind == "point":
            return {
                "light": {
                    "type": "point",
                    "position": list(self.position),
                    "intensity": {"type": "rgb", "value": self.value},
                }
            }
        # A 1.5 x 1.5 square 1.5 above the centre, emitting downwards (rectangle normals are +z).
        mi = require_variant()
        to_world = mi.ScalarTransform4f().translate([0.0, 1.5, 0.0]).rotate([1, 0, 0], 90).scale(0.75)
        return {
            "light": {
                "type": "rectangle",
                "to_world": to_world,
                "emitter": {"type": "area", "radiance": {"type": "rgb", "value": self.value}},
            }
        }
