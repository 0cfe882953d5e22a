"""What decides a pipeline's output: ``PipelineSettings`` (with ``RenderSettings``), checked when made."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..conventions import DEVICES, HELD_OUT_VIEW, IMAGE_SIDES, LIGHT_KINDS, MAX_FIT_STEPS
from ..denoise import DENOISERS
from ..resample import DEFAULT_WORKING_SIZE, validate_working_size
from ..stylizer import (
    validate_scale_structures,
    validate_strength,
)


def default_refinement(config, camera_distance: float | None = None):
    """``mistyle-render``'s refinement schedule (``fit.RefineSettings``) for a checkpoint's ``config``:
    the schedule's defaults with the checkpoint's TV weight and orbit radius."""
    from ..fit import RefineSettings

    distance = config.render.camera_distance if camera_distance is None else camera_distance
    return RefineSettings(tv_weight=config.loss.tv_weight, camera_distance=distance)


def described(value) -> str:
    """``value`` as an error message shows it: short, with its type."""
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape}"
    text = repr(value)
    return f"{text if len(text) <= 60 else text[:57] + '...'} ({type(value).__name__})"


def validate_int(value, name: str, low: int | None = None, high: int | None = None) -> int:
    """``value`` as an int in ``[low, high]`` (a ``None`` bound: none); ``TypeError`` for anything but an
    integer (a bool, a float or a string too), ``ValueError`` out of range, both naming ``name``."""
    bounds = f" in [{low}, {high}]" if None not in (low, high) else f" >= {low}" if low is not None else ""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer{bounds}, got {described(value)}.")
    if (low is not None and value < low) or (high is not None and value > high):
        raise ValueError(f"{name} must be{bounds}, got {value}.")
    return int(value)


def validate_real(value, name: str, accepted: str = "a number") -> float:
    """``value`` as a float; ``TypeError`` naming ``name`` for a string, a bool or anything else that is
    not a real number. Ranges are the caller's (``validate_strength``, ...), which also refuse NaN."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be {accepted}, got {described(value)}.")
    return float(value)


def validate_flag(value, name: str) -> bool:
    """``value`` as a bool; ``TypeError`` naming ``name`` for anything but True or False (a truthy string
    such as ``"no"`` would otherwise switch the option on)."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {described(value)}.")
    return bool(value)


def validate_path(value, name: str, accepted: str = "a file's path") -> None:
    """``None`` or a path (``str`` or ``os.PathLike``); ``TypeError`` naming ``name`` otherwise."""
    import os

    if value is not None and not isinstance(value, (str, os.PathLike)):
        raise TypeError(f"{name} must be {accepted} (a str or Path) or None, got {described(value)}.")


@dataclass
class RenderSettings:
    """How the final images are path traced (``mistyle-render``'s ``--res``, ``--spp``, ...)."""

    res: int = 256
    spp: int = 64
    max_depth: int = -1  # -1: full multiple scattering; 2: single scattering
    light: str = LIGHT_KINDS[0]  # constant[:Le] | envmap:<file.exr>[:scale] | point:x,y,z[:I] | area[:L]
    coat_ior: float | None = None  # a smooth dielectric boundary of this index of refraction
    bricks: int | None = None  # voxels per majorant brick; None: scenes.bricks.DEFAULT_BRICK (0 under a coat)
    view: float = HELD_OUT_VIEW  # the camera's position on the orbit, in [0, 1)
    turntable: int = 0  # > 0: this many views evenly around the orbit from ``view``
    denoise: str = "oidn"  # mistyle.denoise.DENOISERS: Intel Open Image Denoise on the path-traced images, or "none"

    def __post_init__(self):
        # mistyle-render's bounds (render_final.check_options), for settings made in Python.
        from ..scenes.cameras import validate_orbit_position
        from ..scenes.pathtraced import validate_coat_ior, validate_max_depth

        validate_int(self.res, "res", *IMAGE_SIDES)
        validate_int(self.spp, "spp", 1, 1 << 16)
        validate_max_depth(validate_int(self.max_depth, "max_depth"), "max_depth")
        forms = "constant[:Le], envmap:<file.exr>[:scale], point:x,y,z[:intensity] or area[:radiance]"
        if not isinstance(self.light, str):
            raise TypeError(f"light must be a string: {forms}; got {described(self.light)}.")
        if self.light.partition(":")[0] not in LIGHT_KINDS:
            raise ValueError(f"light {self.light!r} is not a known light; give one of {forms}.")
        if self.coat_ior is not None:
            validate_coat_ior(validate_real(self.coat_ior, "coat_ior", "an index of refraction or None"), "coat_ior")
        if self.bricks is not None:
            validate_int(self.bricks, "bricks", 0, 4096)
            if self.bricks and self.coat_ior is not None:
                raise ValueError("bricks needs one medium under a coat (coat_ior set); leave bricks at None or 0.")
        validate_orbit_position(validate_real(self.view, "view", "an orbit position in [0, 1)"), "view")
        validate_int(self.turntable, "turntable", 0, 3600)
        if self.denoise not in DENOISERS:
            raise ValueError(f"denoise must be one of {', '.join(DENOISERS)}, got {self.denoise!r}.")


@dataclass
class PipelineSettings:
    """Everything that decides the pipeline's output, with ``mistyle-render``'s defaults.

    ``None`` fields take the checkpoint's value (``density_scale``, ``camera_distance``) or the
    pipeline's rule (``refine_steps``, ``refine_path_steps``: see ``Pipeline.refinement``)."""

    checkpoint: str | Path | None = None  # a ``mistyle-train`` checkpoint; None: the bundled one
    device: str = "cpu"
    vgg_weights: str | Path | None = None
    strength: float = 1.0
    scale_structures: float = 1.0
    # the longest side stylized: larger grids are stylized on a resampled copy (mistyle.resample); 0: the full grid
    working_size: int = DEFAULT_WORKING_SIZE
    colour_match: bool = True
    refine_steps: int | None = None
    refine_path_steps: int | None = None
    density_scale: float | None = None
    camera_distance: float | None = None
    look_steps: int | None = None  # steps of a look's fit (None: look.LookSettings'); see Pipeline.fits_look
    key_frames: str | None = None  # "0,40,80": the frames the default look is fitted on (None: look.default_key_frames)
    render: RenderSettings = field(default_factory=RenderSettings)

    @property
    def fits_look(self) -> bool:
        """Whether the frames are stylized by a look fitted on them (``look.fit_look`` on a single
        frame, or on a sequence's key frames, ``key_frames`` or ``look.default_key_frames``; then applied
        to every frame) instead of refined or left feed-forward: the default at full strength with the
        colour match, when no refinement steps are named.

        On the held-out split a look has the lowest medians of every metric the benchmark has, and
        matches or beats the refinement it replaced at about the same time (``results/benchmark/``:
        ``look`` against ``default``). Over a sequence, a look fitted on three key frames flickers
        0.4-0.65x as much as the network's frames, and the frames it was not fitted on score within
        1.05x of the key frames (``results/look_sequence/``)."""
        named = self.refine_steps is not None or self.refine_path_steps is not None
        return self.strength == 1.0 and self.colour_match and not named

    def __post_init__(self):
        from ..scenes import validate_density_scale
        from ..scenes.cameras import validate_camera_distance

        validate_path(self.checkpoint, "checkpoint", "a mistyle-train checkpoint's path")
        validate_path(self.vgg_weights, "vgg_weights", "the VGG weights' path")
        if self.device not in DEVICES:
            raise ValueError(f"device must be one of {', '.join(DEVICES)}, got {described(self.device)}.")
        validate_strength(validate_real(self.strength, "strength", "a number in [0, 1]"))
        validate_scale_structures(validate_real(self.scale_structures, "scale_structures"))
        validate_working_size(self.working_size)
        validate_flag(self.colour_match, "colour_match")
        for name in ("refine_steps", "refine_path_steps", "look_steps"):
            if getattr(self, name) is not None:
                validate_int(getattr(self, name), name, 0, MAX_FIT_STEPS)
        if self.density_scale is not None:
            validate_density_scale(validate_real(self.density_scale, "density_scale"))
        if self.camera_distance is not None:
            validate_camera_distance(validate_real(self.camera_distance, "camera_distance"), "camera_distance")
        if self.key_frames is not None and not isinstance(self.key_frames, str):
            raise TypeError(
                f'key_frames must be a string of frame indices such as "0,40,80", got {described(self.key_frames)}.'
            )
        if not isinstance(self.render, RenderSettings):
            raise TypeError(
                f"render must be a RenderSettings (e.g. RenderSettings(res=128)), got {described(self.render)}."
            )
