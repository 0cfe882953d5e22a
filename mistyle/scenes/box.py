"""The medium box: where a voxel grid sits in world space.

This module owns the grid convention used everywhere in mistyle:

* numpy volumes are indexed ``arr[z, y, x]`` (scalars) or ``arr[z, y, x, c]`` (vectors), the
  layout of ``mi.VolumeGrid``, ``gridvolume`` and ``mi.Texture3f``;
* positions are ``(x, y, z)``; +y is up;
* the medium fills an axis-aligned box centred at the origin whose longest side is 1, so voxels
  are cubes of side ``1 / max(Z, Y, X)`` and non-cubic volumes keep their aspect;
* voxel ``(x, y, z)`` is the cube ``[x, x+1] x [y, y+1] x [z, z+1]`` in voxel units; its centre sits
  at texture coordinate ``((x + 0.5) / X, (y + 0.5) / Y, (z + 0.5) / Z)`` in the unit cube.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MediumBox:
    """Axis-aligned box holding a ``(Z, Y, X)`` grid, centred at the origin, longest side 1."""

    shape_zyx: tuple[int, int, int]

    def __post_init__(self):
        shape = tuple(int(n) for n in self.shape_zyx)
        if len(shape) != 3 or min(shape) < 1:
            raise ValueError(f"MediumBox needs a (Z, Y, X) shape with every size >= 1, got {self.shape_zyx}.")
        object.__setattr__(self, "shape_zyx", shape)

    @property
    def resolution_xyz(self) -> np.ndarray:
        """Voxel counts ``(X, Y, Z)``, shape ``(3,)``."""
        z, y, x = self.shape_zyx
        return np.array([x, y, z], dtype=np.float64)

    @property
    def voxel_size(self) -> float:
        """Side of one (cubic) voxel in world units."""
        return 1.0 / max(self.shape_zyx)

    @property
    def extent(self) -> np.ndarray:
        """Side lengths ``(sx, sy, sz)`` of the box; the largest is 1."""
        return self.resolution_xyz * self.voxel_size

    @property
    def bbox_min(self) -> np.ndarray:
        return -0.5 * self.extent

    @property
    def bbox_max(self) -> np.ndarray:
        return 0.5 * self.extent

    def voxel_centre(self, x: float, y: float, z: float) -> np.ndarray:
        """World position ``(3,)`` of the centre of voxel ``(x, y, z)``, i.e. of ``arr[z, y, x]``."""
        return self.bbox_min + (np.array([x, y, z], dtype=np.float64) + 0.5) * self.voxel_size

    def voxel_centres(self) -> np.ndarray:
        """World positions of all voxel centres, shape ``(Z, Y, X, 3)`` with ``(x, y, z)`` last."""
        z, y, x = np.meshgrid(*(np.arange(n) + 0.5 for n in self.shape_zyx), indexing="ij")
        return self.bbox_min + np.stack([x, y, z], axis=-1) * self.voxel_size

    def field_support(self, occupied: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World corners ``(min, max)``, each ``(3,)``, of the box outside which a field that is zero
        off the ``occupied`` voxels (``(Z, Y, X)`` bool) stays zero when interpolated trilinearly with
        clamped edges, as ``mi.Texture3f`` and volpath's ``gridvolume`` do: voxel ``i``'s weight reaches
        half a voxel past its neighbours' centres, ``((i - 1/2) h, (i + 3/2) h)``, and the box clips it.
        A grid with nothing occupied gives the whole box."""
        occupied = np.asarray(occupied, dtype=bool)
        if occupied.shape != self.shape_zyx:
            raise ValueError(f"occupied mask {occupied.shape} does not match the box's grid {self.shape_zyx}.")
        if not occupied.any():
            return self.bbox_min.copy(), self.bbox_max.copy()
        low, high = [], []
        for axis in (2, 1, 0):  # x, y, z
            used = np.flatnonzero(occupied.any(axis=tuple(a for a in range(3) if a != axis)))
            low.append(used[0] - 0.5)
            high.append(used[-1] + 1.5)
        corner_min = np.maximum(self.bbox_min + np.array(low) * self.voxel_size, self.bbox_min)
        corner_max = np.minimum(self.bbox_min + np.array(high) * self.voxel_size, self.bbox_max)
        return corner_min, corner_max

    def world_to_unit(self, p: np.ndarray) -> np.ndarray:
        """Map world positions ``(..., 3)`` to texture coordinates in ``[0, 1]^3`` (``(x, y, z)``)."""
        return (np.asarray(p, dtype=np.float64) - self.bbox_min) / self.extent

    def unit_to_world_matrix(self) -> np.ndarray:
        """4x4 matrix taking the unit cube ``[0,1]^3`` onto the box (a ``gridvolume``'s ``to_world``)."""
        return self.window_to_world_matrix((0, 0, 0), self.shape_zyx)

    def window_to_world_matrix(self, start_zyx, stop_zyx) -> np.ndarray:
        """4x4 matrix taking the unit cube onto the voxels ``[start, stop)`` of the grid (per axis, z, y, x):
        the ``to_world`` of a ``gridvolume`` holding ``arr[z0:z1, y0:y1, x0:x1]`` in place."""
        start = np.asarray(start_zyx, dtype=np.float64)[::-1]
        size = np.asarray(stop_zyx, dtype=np.float64)[::-1] - start
        m = np.diag(np.append(size * self.voxel_size, 1.0))
        m[:3, 3] = self.bbox_min + start * self.voxel_size
        return m

    def cube_to_world_matrix(self) -> np.ndarray:
        """4x4 matrix taking Mitsuba's ``cube`` shape, ``[-1, 1]^3``, onto the box."""
        return np.diag(np.append(0.5 * self.extent, 1.0))
