"""The working resolution: a grid longer than the working size on a side is stylized on a copy
resampled to it, and its albedo resampled back to the full grid for the path trace.

What stylizes a frame looks at small pictures and fields of the box: the look's fit renders 64^2
views, the colour match 32^2 ones, the network's noise fields and kernels act on the box's voxels. At
512^3 they would hold the full grid many times over (``results/memory_trace/``: over 20 GB), for
detail that none of those pictures resolve. So ``WorkingGrid`` stylizes a copy whose longest side is
the working size, and the path tracer renders the full density with the albedo brought back to it:
the density keeps every voxel of its detail, the albedo is as fine as the working grid, and the
network's structures, sized in voxels, are those of a frame at the working size (a 512^3 frame gets
the patterns of a 256^3 one: ``results/working_size_study/``).

- The density is box-averaged (``F.interpolate``'s ``area``): each working voxel holds the mean of
  the voxels it covers, so a ray's optical depth through the box is kept and no medium is dropped.
- The velocities (voxels per frame) are averaged the same way and measured in working voxels.
- The albedo comes back density-weighted: ``up(albedo * density) / up(density)`` with trilinear
  ``up`` (the renderer's own lookup between voxel centres), so a voxel at the medium's edge takes the
  colour of the medium around it, not the albedo of empty working voxels (which nothing renders).
"""

from __future__ import annotations

import numpy as np

DEFAULT_WORKING_SIZE = 256
"""The longest side a grid is stylized at: a 256^3 frame fits this CPU's 24 GB (4.7 GB, ``results/bench_scale/``)."""

MIN_WORKING_SIZE = 16


def validate_working_size(size, name: str = "working_size") -> int:
    """``size`` as the longest side stylized (0: the full grid, however large); ``ValueError`` otherwise."""
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)):
        raise TypeError(f"{name} must be a whole number of voxels (e.g. 256), or 0 for the full grid, got {size!r}.")
    if size != 0 and not MIN_WORKING_SIZE <= size <= 4096:
        raise ValueError(
            f"{name} must be 0 (stylize the full grid) or lie in [{MIN_WORKING_SIZE}, 4096] voxels, got {size}."
        )
    return int(size)


def working_shape(shape: tuple, size: int) -> tuple | None:
    """The shape a grid of ``shape (Z, Y, X)`` is stylized at: every side scaled by ``size / longest side``
    (the voxels stay cubes), or None when the grid is no larger than ``size`` (or ``size`` is 0)."""
    longest = max(shape)
    if size == 0 or longest <= size:
        return None
    factor = size / longest
    return tuple(min(n, max(1, round(n * factor))) for n in shape)


class WorkingGrid:
    """The resampling between a full grid of ``full (Z, Y, X)`` and its working copy of ``shape``."""

    def __init__(self, full: tuple, shape: tuple):
        self.full = tuple(int(n) for n in full)
        self.shape = tuple(int(n) for n in shape)

    @classmethod
    def of(cls, shape: tuple, size: int) -> WorkingGrid | None:
        """The working grid of a frame of ``shape`` at working size ``size`` (``working_shape``), or None."""
        working = working_shape(tuple(shape), size)
        return None if working is None else cls(shape, working)

    def describe(self) -> str:
        full, work = ("x".join(map(str, shape[::-1])) for shape in (self.full, self.shape))
        return f"stylized on a {work} copy of the {full} grid (voxels, X x Y x Z)"

    def density(self, grid: np.ndarray) -> np.ndarray:
        """``grid (Z, Y, X)`` box-averaged to the working shape, float32."""
        import torch

        with torch.no_grad():
            return _averaged(torch.from_numpy(np.ascontiguousarray(grid, dtype=np.float32)), self.shape).numpy()

    def velocity(self, velocity: np.ndarray) -> np.ndarray:
        """A velocity ``(Z, Y, X, 3)`` in full voxels per frame, components ``(x, y, z)`` (``warp``'s
        convention), as the working grid's: box-averaged, in working voxels per frame."""
        import torch
        import torch.nn.functional as F

        tensor = torch.from_numpy(np.ascontiguousarray(velocity, dtype=np.float32)).permute(3, 0, 1, 2)[None]
        with torch.no_grad():
            averaged = F.interpolate(tensor, size=self.shape, mode="area")[0].permute(1, 2, 3, 0)
        # component x runs along axis X (the last), z along axis Z (the first)
        ratios = [self.shape[2] / self.full[2], self.shape[1] / self.full[1], self.shape[0] / self.full[0]]
        return np.ascontiguousarray((averaged * torch.tensor(ratios)).numpy(), dtype=np.float32)

    def albedo(self, albedo: np.ndarray, working_density: np.ndarray) -> np.ndarray:
        """The working grid's ``albedo (z, y, x, 3)`` on the full grid ``(Z, Y, X, 3)``: interpolated
        trilinearly between voxel centres, weighted by the working density (``working_density``, this
        grid's ``density`` of the frame; ``_normalised``). One channel at a time, so that the full grid
        is held about twice over, not eight times."""
        return self._normalised(albedo, working_density, self.full, _upsampled)

    def working_albedo(self, albedo: np.ndarray, density: np.ndarray) -> np.ndarray:
        """A full grid's ``albedo (Z, Y, X, 3)`` on the working grid: each working voxel the mean albedo of
        the full voxels it covers, weighted by their ``density`` (``_normalised``)."""
        return self._normalised(albedo, density, self.shape, _averaged)

    @staticmethod
    def _normalised(albedo: np.ndarray, density: np.ndarray, shape: tuple, resample) -> np.ndarray:
        """``resample(albedo * w) / resample(w)`` per channel with ``w = density + floor``: a normalised
        convolution, whose weights take the medium's colours where it is and the plain resampling of
        the albedo far from it (``floor``, a millionth of the densest voxel, decides only there)."""
        import torch

        out = np.empty((*shape, 3), dtype=np.float32)
        written = torch.from_numpy(out)
        with torch.no_grad():
            weights = torch.from_numpy(np.ascontiguousarray(density, dtype=np.float32))
            weights = weights + (float(weights.max()) * WEIGHT_FLOOR or 1.0)  # all zero: the plain resampling
            total = resample(weights, shape)
            for channel in range(3):
                values = torch.from_numpy(np.ascontiguousarray(albedo[..., channel], dtype=np.float32))
                written[..., channel] = resample(values * weights, shape).div_(total).clamp_(0.0, 1.0)
        return out


WEIGHT_FLOOR = 1e-6
"""The weight every voxel has in ``WorkingGrid``'s albedo resampling, relative to the densest voxel."""


def _upsampled(field, shape: tuple):
    """``field (z, y, x)`` interpolated trilinearly to ``shape`` between voxel centres, clamped at the faces."""
    import torch.nn.functional as F

    return F.interpolate(field[None, None], size=shape, mode="trilinear", align_corners=False)[0, 0]


def _averaged(field, shape: tuple):
    """``field (Z, Y, X)`` box-averaged to ``shape``."""
    import torch.nn.functional as F

    return F.interpolate(field[None, None], size=shape, mode="area")[0, 0]
