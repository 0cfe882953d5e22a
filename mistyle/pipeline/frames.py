"""What a pipeline works on and returns: ``Frames`` (the densities of one output and what is computed
once per frame) and ``Stylization``."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np


def flicker_report(albedos: list, frames, suffix: str = "") -> dict:
    """How much a sequence's ``albedos`` flicker, for ``report.json``: ``temporal_flicker{suffix}``
    (``objective.metrics.temporal_flicker``, each frame against the previous one warped by its
    velocity), or ``temporal_flicker{suffix}_unwarped`` (mean absolute change) when the frames carry
    no velocity, from the first frame that holds medium to the last (``Frames.holding``); nothing for
    a single frame."""
    from ..objective.metrics import temporal_flicker

    holding = frames.holding
    if not frames.sequence or len(holding) < 2:
        return {}
    span = slice(holding[0], holding[-1] + 1)  # frames before the emitter starts hold no stylized albedo
    stacked = np.stack(albedos[span])
    if frames.velocities is not None:
        return {f"temporal_flicker{suffix}": temporal_flicker(stacked, np.stack(frames.velocities[span]))}
    return {f"temporal_flicker{suffix}_unwarped": float(np.mean(np.abs(np.diff(stacked, axis=0))))}


@dataclass
class Frames:
    """The density frames one output stylizes, and what is computed once per frame."""

    densities: list  # (Z, Y, X) float32 each, all one shape
    velocities: list | None  # (Z, Y, X, 3) each, when every frame has one
    density_scale: float
    # advection.TextureMotion: the velocities a look's texture follows, from those of the frames before
    # ``first`` (a chunk's), or None where the frames carry none
    motion: object = None
    first: int = 0  # the sequence's index of densities[0]
    # resample.WorkingGrid: these frames are the working copy of a larger grid's (``at_working_size``)
    working_grid: object = None
    _prepared: dict = field(default_factory=dict, repr=False)
    _working: dict = field(default_factory=dict, repr=False)  # working size -> Frames

    @property
    def sequence(self) -> bool:
        return len(self.densities) > 1

    @cached_property
    def holding(self) -> list[int]:
        """The frames that hold medium enough to stylize (``stylizer.holds_medium``): all of one frame, and
        of a sequence all but those before its emitter starts (``filled``)."""
        from ..stylizer import holding_frames

        return holding_frames(self.densities)

    def filled(self, albedos: list) -> list:
        """An albedo per frame from ``albedos``, one per frame of ``holding`` in turn: the others (frames
        with too little medium to stylize) hold ``stylizer.EMPTY_FRAME_ALBEDO``, one grid they share."""
        from ..stylizer import empty_frame_albedo

        if len(albedos) == len(self.densities):
            return list(albedos)
        empty = empty_frame_albedo(self.densities[0].shape)
        stylized = dict(zip(self.holding, albedos, strict=True))
        return [stylized.get(index, empty) for index in range(len(self.densities))]

    def empty_note(self) -> str | None:
        """What the log and the report say of the frames outside ``holding``, or None."""
        from ..stylizer import EMPTY_FRAME_ALBEDO, MIN_MEDIUM_VOXELS, frame_list

        empty = [index for index in range(len(self.densities)) if index not in self.holding]
        if not empty:
            return None
        return (
            f"frame(s) {frame_list([self.first + index for index in empty])} hold no medium to stylize (fewer than "
            f"{MIN_MEDIUM_VOXELS} non-zero voxels): rendered as they are, albedo {EMPTY_FRAME_ALBEDO:g}"
        )

    def phases(self, frame: int) -> list | None:
        """Frame ``frame``'s advected texture fields (``advection.TextureMotion.phases``), or None."""
        return None if self.motion is None else self.motion.phases(self.first + frame)

    def at_working_size(self, size: int) -> Frames:
        """These frames as they are stylized at working size ``size`` (``resample``): themselves when
        no side is longer, else their copy resampled to it (densities, velocities, the texture's
        motion), made once."""
        from ..resample import WorkingGrid

        grid = WorkingGrid.of(self.densities[0].shape, size)
        if grid is None:
            return self
        if size not in self._working:
            resampled: dict = {}  # the motion's velocities are often the frames' own arrays

            def velocity(array):
                if id(array) not in resampled:
                    resampled[id(array)] = grid.velocity(array)
                return resampled[id(array)]

            motion = self.motion
            if motion is not None:
                motion = type(motion)([velocity(v) for v in motion.velocities], motion.begin, motion.period)
            velocities = None if self.velocities is None else [velocity(v) for v in self.velocities]
            densities = [grid.density(density) for density in self.densities]
            self._working[size] = Frames(densities, velocities, self.density_scale, motion, self.first, grid)
        return self._working[size]

    def full_albedos(self, albedos: list) -> list:
        """The albedos of these frames, a working copy's (``at_working_size``), on the full grid."""
        return [self.working_grid.albedo(albedo, density) for albedo, density in zip(albedos, self.densities)]

    def prepared(self, frame: int):
        """The frame's density prepared for the fast layer (its Ls grid), computed once."""
        from ..integrators import prepare_density

        if frame not in self._prepared:
            self._prepared[frame] = prepare_density(self.densities[frame], self.density_scale)
        return self._prepared[frame]


@dataclass
class Stylization:
    """What ``Pipeline.stylize`` made for one (density, style) pair."""

    frames: Frames
    network: list  # (Z, Y, X, 3) per frame: the feed-forward albedo (network, then the colour match)
    albedos: list  # (Z, Y, X, 3) per frame: what is path traced (refined, else ``network``)
    target: np.ndarray  # (H, W, 3) display RGB: the picture the result is refined and measured against
    refinement: object  # the fit.RefineSettings that ran (0 steps: none)
    report: dict  # seconds per stage, temporal flicker of sequences
    notes: list
    look: object = None  # the look.Look fitted on the frame(s) and applied (Pipeline.fits_look), or None

    @property
    def refined(self) -> bool:
        """Whether ``albedos`` were refined from the feed-forward ``network`` albedos (by refinement steps,
        or by a look fitted on the frame)."""
        return self.albedos is not self.network
