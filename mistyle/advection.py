"""Texture advection: a look's texture carried by a sequence's velocities, regenerated before it tears.

A look's texture (``look.Look.texture``) lies over the medium's box. Looked up where each voxel is, it
stays put while the smoke flows through it. Looked up at *advected box coordinates* instead, it
travels with the smoke: a coordinate field ``φ`` starts as each voxel's own place at a start frame
``s`` and is carried by every frame's velocity after it,

    φ_s(x) = x,        φ_{t+1}(x) = φ_t(x - U_t(x))        (``warp.semi_lagrangian_warp``),

so frame ``t`` reads the texture at ``φ_t(x)``: where the smoke at ``x`` was at frame ``s``. Carried
for long, the field stretches and folds with the flow, and so would the strokes. As in Neyret's
advected textures (2003), two fields run half a period apart; each restarts from the identity every
``period`` frames, at the moment its weight ``sin²(π·age/period)`` is zero, and the two weights sum to
one. Coordinates, not colours, are advected: a linear field survives trilinear interpolation
unblurred, so the texture keeps its detail.

Blending two differently deformed copies of the texture lowers its contrast where they disagree, so
the blend's deviations from the texture's mean are rescaled, per channel, to the spread the phases
have on their own (``blend_phases``).

Every frame's fields depend only on the velocities since their start frame, at most ``period`` frames
back, never on where a computation began: a chunk of frames (``mistyle-render --frames``) computes the
same fields, bit for bit, as the whole sequence does, from the velocities of the frames before it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

ADVECTION_PERIOD = 8
"""Frames between a field's restarts. Shorter restarts blend more often (colours change along the
flow), longer ones let the strokes stretch with it (``experiments/mantaflow_flicker.py`` measures
both on a real sequence)."""


def first_needed(frame: int, period: int = ADVECTION_PERIOD) -> int:
    """The first frame whose velocity frame ``frame``'s fields depend on: a chunk of a sequence starting
    at ``frame`` needs the velocities from there on."""
    return max(0, frame - period + 1)


def identity_coordinates(shape: tuple):
    """``(1, 3, Z, Y, X)`` float32 tensor: each voxel's place in the box as ``grid_sample`` reads it
    (``align_corners=False``; components ``(x, y, z)`` in [-1, 1])."""
    import torch

    axes = [(torch.arange(n, dtype=torch.float32) + 0.5) * (2.0 / n) - 1.0 for n in shape]
    z, y, x = torch.meshgrid(*axes, indexing="ij")
    return torch.stack([x, y, z])[None]


@dataclass(frozen=True)
class Phase:
    """One advected field of a frame: ``coordinates (1, 3, Z, Y, X)`` (``identity_coordinates``' convention)
    and its ``weight`` in the blend."""

    coordinates: object
    weight: float


@dataclass
class TextureMotion:
    """The velocities a look's texture follows through a sequence, and its fields per frame.

    ``velocities``: frame ``begin + i``'s velocity, ``(Z, Y, X, 3)`` in voxels per frame, components
    ``(x, y, z)`` (``warp``'s convention; frame t's carries it to frame t+1). A chunk of a sequence
    starting at frame ``f`` holds the velocities from ``first_needed(f)`` on."""

    velocities: list
    begin: int = 0
    period: int = ADVECTION_PERIOD
    _carried: dict = field(default_factory=dict, repr=False)  # start frame -> (frame, coordinates)

    def __post_init__(self):
        if self.period < 2 or self.period % 2:
            raise ValueError(f"A texture's advection period must be an even number of frames >= 2, got {self.period}.")

    def first_needed(self, frame: int) -> int:
        return first_needed(frame, self.period)

    def phases(self, frame: int) -> list[Phase] | None:
        """Frame ``frame``'s fields (sequence index), or None where the frame reads the texture in place
        (its only field starts there: the first frame, for one)."""
        starts: dict[int, float] = {}
        for offset in (0, self.period // 2):
            age = (frame - offset) % self.period
            start = max(0, frame - age)
            # A field that would start before the sequence starts at its first frame, the velocities
            # before it being unknown; two fields from one start are one.
            starts[start] = starts.get(start, 0.0) + math.sin(math.pi * age / self.period) ** 2
        if list(starts) == [frame]:
            return None
        return [Phase(self._coordinates(start, frame), weight) for start, weight in starts.items() if weight > 0.0]

    def _coordinates(self, start: int, frame: int):
        """The field started at ``start`` carried to ``frame``: from the furthest this motion has carried
        it, else from the identity."""
        from .warp import semi_lagrangian_warp

        if start < self.begin:
            raise ValueError(
                f"frame {frame}'s texture follows the velocities from frame {start} on, and this motion holds "
                f"them from frame {self.begin}: load the frames from {start} (first_needed)"
            )
        reached, coordinates = self._carried.get(start, (start, None))
        if reached > frame:
            reached, coordinates = start, None
        if coordinates is None:
            coordinates = identity_coordinates(self._velocity(start).shape[:3])
        for step in range(reached, frame):
            coordinates = semi_lagrangian_warp(coordinates, self._flow(step))
        self._carried = {key: value for key, value in self._carried.items() if key >= self.first_needed(frame)}
        self._carried[start] = (frame, coordinates)
        return coordinates

    def _velocity(self, frame: int) -> np.ndarray:
        index = frame - self.begin
        if not 0 <= index < len(self.velocities):
            raise ValueError(
                f"this motion holds the velocities of frames {self.begin}-{self.begin + len(self.velocities) - 1}, "
                f"not frame {frame}'s"
            )
        return self.velocities[index]

    def _flow(self, frame: int):
        import torch

        velocity = np.ascontiguousarray(self._velocity(frame), dtype=np.float32)
        return torch.from_numpy(velocity).permute(3, 0, 1, 2)[None]


def sample_in_box(field, coordinates):
    """``field (C, d, h, w)`` over the box read at ``coordinates (1, 3, Z, Y, X)``: ``(C, Z, Y, X)``,
    trilinear, clamped at the box's faces. At ``identity_coordinates`` this is ``field`` stretched
    over a ``(Z, Y, X)`` grid as ``F.interpolate(..., mode="trilinear", align_corners=False)`` does."""
    import torch.nn.functional as F

    grid = coordinates.permute(0, 2, 3, 4, 1).to(field.dtype)
    return F.grid_sample(field[None], grid, mode="bilinear", padding_mode="border", align_corners=False)[0]


def blend_phases(field, phases: list[Phase], shape: tuple):
    """``field (C, d, h, w)`` over the box as a frame of ``shape (Z, Y, X)`` shows it through its advected
    ``phases``: ``(C, Z, Y, X)``.

    The weighted sum of the phases' readings, its deviations from ``field``'s mean rescaled per channel
    so that their spread is the phases' own weighted spread: two fields that disagree would otherwise
    average each other's strokes away in mid-blend."""
    import torch
    import torch.nn.functional as F

    mean = field.reshape(field.shape[0], -1).mean(dim=1).view(-1, 1, 1, 1)
    readings, spreads, blended = [], [], 0.0
    for phase in phases:
        coordinates = phase.coordinates
        if tuple(coordinates.shape[2:]) != tuple(shape):
            coordinates = F.interpolate(coordinates, size=tuple(shape), mode="trilinear", align_corners=False)
        reading = sample_in_box(field, coordinates) - mean
        readings.append(reading)
        spreads.append(phase.weight * reading.square().mean(dim=(1, 2, 3)))
        blended = blended + phase.weight * reading
    if len(readings) == 1:
        return mean + blended / phases[0].weight
    wanted = torch.stack(spreads).sum(dim=0)
    had = blended.square().mean(dim=(1, 2, 3))
    scale = torch.sqrt(wanted / had.clamp_min(1e-12)).view(-1, 1, 1, 1)
    return mean + blended * scale
