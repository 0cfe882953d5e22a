"""How mistyle lays out its VDB files: the grids' names, where a grid sits (``VdbTransform``, index to
world), which way is up (``upright`` turns a Z-up world's grid to mistyle's +y up) and what mistyle's files
say of themselves (``mistyle_metadata``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..conventions import UP_AXES

DENSITY_GRID = "density"
ALBEDO_GRID = "Cd"


@dataclass(frozen=True)
class VdbTransform:
    """Where a grid sits: the index-to-world matrix and the index of array element ``[0, 0, 0]``.

    ``matrix``: 4x4 float64 acting on column vectors, ``world = matrix @ (i, j, k, 1)``.
    ``index_min``: ``(i, j, k) = (x, y, z)`` index of ``arr[0, 0, 0]``.
    """

    matrix: np.ndarray
    index_min: tuple[int, int, int] = (0, 0, 0)

    def __post_init__(self):
        matrix = np.array(self.matrix, dtype=np.float64)
        if matrix.shape != (4, 4) or not np.all(np.isfinite(matrix)):
            raise ValueError(f"A VDB transform needs a finite 4x4 index-to-world matrix, got shape {matrix.shape}.")
        if not np.array_equal(matrix[3], [0.0, 0.0, 0.0, 1.0]):
            raise ValueError(
                "The index-to-world matrix must be affine (last row 0, 0, 0, 1; column vectors, "
                f"translation in matrix[:3, 3]), got last row {matrix[3].tolist()}."
            )
        if np.linalg.cond(matrix[:3, :3]) > 1e12:
            raise ValueError("The index-to-world matrix is singular; voxels need a non-zero size along every axis.")
        index_min = tuple(self.index_min)
        if len(index_min) != 3 or not all(float(v).is_integer() for v in index_min):
            raise ValueError(f"index_min must be three integers (i, j, k), got {self.index_min}.")
        matrix.flags.writeable = False  # frozen means frozen
        object.__setattr__(self, "matrix", matrix)
        object.__setattr__(self, "index_min", tuple(int(v) for v in index_min))

    def __eq__(self, other):
        if not isinstance(other, VdbTransform):
            return NotImplemented
        return self.index_min == other.index_min and np.array_equal(self.matrix, other.matrix)

    def __hash__(self):
        return hash((self.index_min, self.matrix.tobytes()))

    @property
    def voxel_size(self) -> np.ndarray:
        """World length of one voxel step along ``i``, ``j`` and ``k`` (= x, y, z), shape ``(3,)``."""
        return np.linalg.norm(self.matrix[:3, :3], axis=0)

    def index_to_world(self, points_xyz) -> np.ndarray:
        """World positions ``(..., 3)`` of index coordinates ``(..., 3)`` ordered ``(i, j, k) = (x, y, z)``."""
        points = np.asarray(points_xyz, dtype=np.float64)
        if points.shape[-1:] != (3,):
            raise ValueError(f"Index coordinates are (..., 3) arrays ordered (i, j, k), got shape {points.shape}.")
        return points @ self.matrix[:3, :3].T + self.matrix[:3, 3]

    def voxel_centre(self, x: float, y: float, z: float) -> np.ndarray:
        """World position ``(3,)`` of the centre of array element ``arr[z, y, x]``."""
        return self.index_to_world(np.add(self.index_min, (x, y, z)))

    def world_bbox(self, shape_zyx) -> tuple[np.ndarray, np.ndarray]:
        """World-axis-aligned ``(min, max)`` corners (each ``(3,)``) around the cells of a ``(Z, Y, X)`` array.

        Voxel centres sit at integer index coordinates, so the cells span ``index_min - 0.5`` to
        ``index_max + 0.5``; a rotated grid gives the box around its eight corners.
        """
        size_xyz = np.array(shape3(shape_zyx)[::-1], dtype=np.float64)
        low = np.array(self.index_min, dtype=np.float64) - 0.5
        corners = np.array([[low[a] + size_xyz[a] * bit for a, bit in enumerate(bits)] for bits in np.ndindex(2, 2, 2)])
        world = self.index_to_world(corners)
        return world.min(axis=0), world.max(axis=0)

    @classmethod
    def for_medium_box(cls, shape_zyx, up: str = "y") -> VdbTransform:
        """The transform that puts a ``(Z, Y, X)`` grid where mistyle renders it (``mistyle.scenes.box``).

        The medium box is centred at the origin with its longest side 1 and cubic voxels of side
        ``1 / max(Z, Y, X)``; the centre of ``arr[z, y, x]`` is ``bbox_min + (x + 0.5, y + 0.5, z + 0.5) *
        voxel_size``. For densities that came from a file without a transform of its own. ``up``: the
        world up axis of the scene the file goes to (``up_axis_matrix``): mistyle's up (+y) becomes it.
        """
        z, y, x = shape3(shape_zyx)
        voxel = 1.0 / max(z, y, x)
        bbox_min = -0.5 * voxel * np.array([x, y, z], dtype=np.float64)
        matrix = np.diag([voxel, voxel, voxel, 1.0])
        matrix[:3, 3] = bbox_min + 0.5 * voxel
        return cls(up_axis_matrix(up) @ matrix, (0, 0, 0))


def up_axis_matrix(up: str) -> np.ndarray:
    """4x4 (column vectors) from mistyle's world (+y up, the camera orbit's axis) to a world whose up
    axis is ``up`` (``conventions.UP_AXES``): the identity for ``y``; for ``z`` (Blender) the rotation of
    +90 degrees about x, ``(x, y, z) -> (x, -z, y)``, so mistyle's front view (from +z) looks along +y in
    the new world, Blender's front. Entries are 0 and +-1, so it moves a matrix without rounding."""
    if up == "y":
        return np.eye(4)
    if up == "z":
        return np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    raise ValueError(f"The up axis is one of {', '.join(UP_AXES)}, got {up!r}.")


def upright(array: np.ndarray, transform: VdbTransform, up: str) -> tuple[np.ndarray, VdbTransform]:
    """``array`` (``(Z, Y, X)`` or ``(Z, Y, X, 3)``, as read) turned so that its Y axis, the one mistyle
    renders as up, is the index axis that points most along the world's ``up`` axis, and the transform
    that keeps every voxel where it was in the world.

    The turn is a proper rotation of the index axes (the image is not mirrored): the chosen axis becomes
    j, and of the other two the first in i, j, k order becomes i. Files whose j axis already points up
    come back unchanged (the same objects). The array is copied, not resampled, so values are exact.
    """
    world_up = up_axis_matrix(up)[:3, 1]
    linear = transform.matrix[:3, :3]
    alignment = world_up @ linear  # per index axis i, j, k: its world direction's component along up
    axis = int(np.argmax(np.abs(alignment)))
    sign = 1 if alignment[axis] > 0 else -1
    if axis == 1 and sign > 0:
        return array, transform
    # Columns: the old index axes that the new i, j, k run along (signed unit vectors).
    new_to_old = np.zeros((3, 3))
    new_to_old[axis, 1] = sign
    first = min(a for a in range(3) if a != axis)
    new_to_old[first, 0] = 1.0
    new_to_old[:, 2] = np.cross(new_to_old[:, 0], new_to_old[:, 1])
    size_ijk = np.array(array.shape[:3][::-1])
    # Array axes in (i, j, k) order first: element [z, y, x] is index (x, y, z).
    vector = array.ndim == 4
    ijk = array.transpose((2, 1, 0, 3) if vector else (2, 1, 0))
    order = [int(np.flatnonzero(new_to_old[:, n])[0]) for n in range(3)]
    turned = ijk.transpose(order + ([3] if vector else []))
    flips = tuple(n for n in range(3) if new_to_old[order[n], n] < 0)
    if flips:
        turned = np.flip(turned, axis=flips)
    turned = np.ascontiguousarray(turned.transpose((2, 1, 0, 3) if vector else (2, 1, 0)))
    # New local index n maps to old index index_min + new_to_old @ n + offset (offset: the flipped axes' far end).
    offset = np.zeros(3)
    for n in flips:
        offset[order[n]] = size_ijk[order[n]] - 1
    to_old = np.eye(4)
    to_old[:3, :3] = new_to_old
    to_old[:3, 3] = np.asarray(transform.index_min, dtype=np.float64) + offset
    return turned, VdbTransform(transform.matrix @ to_old, (0, 0, 0))


def shape3(shape_zyx) -> tuple[int, int, int]:
    shape = tuple(int(n) for n in shape_zyx)
    if len(shape) != 3 or min(shape) < 1:
        raise ValueError(f"A grid shape is (Z, Y, X) with every size >= 1, got {tuple(shape_zyx)}.")
    return shape


# ----------------------------------------------------------------------------- what mistyle's files say
UP_AXIS_KEY = "mistyle_up_axis"


def mistyle_metadata(
    transform: VdbTransform, shape_zyx, *, density_scale: float, up: str, style: str, checkpoint: str
) -> dict:
    """The metadata mistyle writes on ``volume.vdb`` (file and grids): what a Blender or Houdini user
    needs to render the medium as mistyle did. ``shape_zyx``: the grids' array shape.

    ``mistyle_density_scale`` is mistyle's, per unit of its medium box (longest side 1);
    ``mistyle_world_density_scale`` is the same extinction per unit of the file's world, what to type into
    Blender's Principled Volume Density or Houdini's density scale (``sigma_t = it * density``)."""
    from ..version import __version__

    voxel = transform.voxel_size
    longest = float(np.max(np.array(shape3(shape_zyx)[::-1]) * voxel))
    return {
        "mistyle_version": __version__,
        "mistyle_style": style,
        "mistyle_checkpoint": checkpoint,
        "mistyle_density_scale": float(density_scale),
        "mistyle_world_density_scale": float(density_scale) / longest,
        "mistyle_albedo": f"'{ALBEDO_GRID}' is the single-scattering albedo, linear RGB in [0, 1]",
        UP_AXIS_KEY: up,
        "mistyle_units": f"world units of the transform; the medium's longest side is {longest:.6g} of them",
    }


def recorded_up_axis(file_metadata: dict) -> str:
    """The up axis a file mistyle wrote records, else ``y`` (OpenVDB's and Houdini's convention)."""
    up = str(file_metadata.get(UP_AXIS_KEY, "y")).lower()
    return up if up in UP_AXES else "y"
