"""The medium split into bricks, each with its own majorant, for faster path tracing of sparse volumes.

Mitsuba's ``heterogeneous`` medium samples free-flight distances against one majorant, the largest
extinction in its grid. In smoke, a dense core sets that majorant for the whole box, so a path
through the thin wisps around it makes many null collisions per real one. Here the box is cut into
cubic bricks of ``brick`` voxels. Bricks without density are left empty (vacuum, crossed in one
step). The others are grouped by their largest density into a few majorant levels (``brick_levels``),
and each level is one medium holding only its bricks' part of the grids, so its majorant is its own
maximum. (One medium per brick would be tighter still but is slower: every medium is a separate
dispatch in each tracking step.) The faces between regions of different media are ``null`` meshes
whose two sides name the media (Mitsuba's interior/exterior), so ``volpath`` changes medium as a
path crosses them. Null interactions do not count towards ``max_depth``.

The field is unchanged: a brick's grids carry one extra voxel on each side (where the volume has
one), so trilinear interpolation inside the brick sees the same eight voxels as in the whole grid,
and a brick is empty only when it and that halo hold no density. Every brick's medium therefore
returns the whole medium's extinction and albedo at every point inside the brick, and the render
has the same expectation as ``medium.medium_cube`` (tested against it).

Not for a dielectric coat (the box is then an optical boundary) or for ``prbvolpath`` refinement
(which updates one albedo grid by its key).
"""

from __future__ import annotations

import numpy as np

from ..backend import require_variant
from .box import MediumBox
from .medium import heterogeneous_medium

DEFAULT_BRICK = 8
DEFAULT_LEVELS = 4
"""Chosen with ``experiments/bench_pathtrace.py --sweep`` (bundled smoke at 64^3 and 128^3, 256^2, 64 spp;
the figures: docs/performance.md, section 3): the fastest to equal noise of 4, 8 and 16 voxels and 1 to 8
levels. More than 4 levels do not pay: a medium per level costs a dispatch in every tracking step, and
most smoke bricks fall in the last level anyway."""


def brick_levels(density: np.ndarray, brick: int, levels: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """Group the bricks by their largest density (halo included) into majorant levels.

    ``brick`` (voxels a side) larger than the grid's longest side is the whole grid as one brick.

    Returns ``(level, edges)``: ``level (BZ, BY, BX)`` int, -1 for bricks without density and
    ``0 .. levels-1`` otherwise, level ``k`` holding the bricks whose maximum lies in
    ``(m / 2^(k+1), m / 2^k]`` of the volume's maximum ``m`` (the last level takes everything
    below); ``edges[axis]`` are the voxel bounds of the bricks along z, y, x.
    """
    if int(brick) != brick or brick < 1:
        raise ValueError(f"brick must be a positive number of voxels, got {brick!r}.")
    if int(levels) != levels or levels < 1:
        raise ValueError(f"levels must be a positive integer, got {levels!r}.")
    # A brick as long as the grid already holds all of it along every axis: larger ones are that one brick.
    brick = min(int(brick), max(density.shape))
    edges = [np.unique(np.minimum(np.arange(0, n + brick, brick), n)) for n in density.shape]
    # Each voxel's 3x3x3 maximum, then its maximum over each brick: the brick's peak with its halo.
    padded = np.pad(np.asarray(density, dtype=np.float64), 1)
    grown = np.zeros(density.shape)
    z, y, x = density.shape
    for dz, dy, dx in np.ndindex(3, 3, 3):
        np.maximum(grown, padded[dz : dz + z, dy : dy + y, dx : dx + x], out=grown)
    # Segment maxima along each axis in turn: memory stays that of the grid, whatever the brick.
    peak = grown
    for axis, bounds in enumerate(edges):
        peak = np.maximum.reduceat(peak, bounds[:-1], axis=axis)
    level = np.full(peak.shape, -1, dtype=np.int64)
    top = peak.max()
    if top > 0:
        occupied = peak > 0
        level[occupied] = np.minimum(np.floor(np.log2(top / peak[occupied])), levels - 1).astype(np.int64)
    return level, edges


def bricked_media(
    density: np.ndarray,
    density_scale: float,
    albedo: np.ndarray,
    brick: int = DEFAULT_BRICK,
    levels: int = DEFAULT_LEVELS,
) -> dict:
    """Scene entries (``null`` face meshes carrying the media) that replace ``medium.medium_cube``.

    Args:
        density: ``(Z, Y, X)`` >= 0; albedo: ``(Z, Y, X, 3)``; density_scale: as ``heterogeneous_medium``.
        brick: voxels per brick side.
        levels: number of majorant levels (media); see ``brick_levels``.

    Returns:
        a dict to merge into a scene dictionary: one ``brick_faces_A_B`` mesh per pair of regions
        that touch (``A``, ``B``: level or ``vacuum``), already instantiated, with its media.
    """
    mi = require_variant()
    box = MediumBox(density.shape)
    level, edges = brick_levels(density, brick, levels)
    media = {
        int(k): mi.load_dict(_level_medium(density, density_scale, albedo, level, edges, k))
        for k in np.unique(level[level >= 0])
    }

    # Faces perpendicular to each axis where the media on the two sides differ, one mesh per pair
    # (below, above). Each triangle's geometric normal points to +axis, so the region above is the
    # mesh's exterior (Mitsuba: the target medium of a direction with dot(n, d) > 0).
    # Meshes, not ``rectangle`` shapes: through rectangles, volpath renders a thin medium ~1% too
    # bright (measured against the box's ``cube`` and against meshes; tests/test_bricks.py).
    quads: dict[tuple[int, int], list[np.ndarray]] = {}
    for axis in range(3):  # 0: z, 1: y, 2: x (grid order)
        padded = np.pad(level, [(1, 1) if a == axis else (0, 0) for a in range(3)], constant_values=-1)
        below = np.take(padded, np.arange(0, padded.shape[axis] - 1), axis=axis)
        above = np.take(padded, np.arange(1, padded.shape[axis]), axis=axis)
        for position in zip(*np.nonzero(below != above)):
            pair = (int(below[position]), int(above[position]))
            quads.setdefault(pair, []).append(_quad(box, edges, axis, position))
    entries = {}
    for (inner, outer), corners in quads.items():
        name = f"brick_faces_{_region_name(inner)}_{_region_name(outer)}"
        entries[name] = _face_mesh(mi, name, np.stack(corners), media.get(inner), media.get(outer))
    return entries


def _level_medium(density, density_scale, albedo, level, edges, k) -> dict:
    """Level ``k``'s medium: its bricks' density and albedo with their halos, zero elsewhere, cropped
    to the bounding box of those windows (its maximum is the level's majorant)."""
    box = MediumBox(density.shape)
    mask = np.zeros(density.shape, dtype=bool)
    for position in zip(*np.nonzero(level == k)):
        mask[_window(edges, position, density.shape)] = True
    bounds = [np.nonzero(mask.any(axis=tuple(b for b in range(3) if b != a)))[0] for a in range(3)]
    window = tuple(slice(int(b[0]), int(b[-1]) + 1) for b in bounds)
    grid = np.where(mask[window], density[window], 0.0).astype(np.float32)
    unit_to_world = box.window_to_world_matrix([w.start for w in window], [w.stop for w in window])
    return heterogeneous_medium(grid, density_scale, np.ascontiguousarray(albedo[window]), unit_to_world)


def _window(edges, position, shape) -> tuple[slice, slice, slice]:
    """Voxel ranges of the brick at ``position`` (z, y, x) with a one-voxel halo, clipped to the grid."""
    return tuple(
        slice(max(int(edges[a][position[a]]) - 1, 0), min(int(edges[a][position[a] + 1]) + 1, shape[a]))
        for a in range(3)
    )


def _region_name(level: int) -> str:
    return "vacuum" if level < 0 else str(level)


def _quad(box: MediumBox, edges, axis: int, position) -> np.ndarray:
    """Corners ``(4, 3)`` (world x, y, z) of the face on plane ``edges[axis][position[axis]]`` over the
    cross-section of brick ``position``, counter-clockwise seen from +axis."""
    lo = np.array([edges[a][position[a]] for a in range(3)], dtype=np.float64)
    hi = np.array(
        [edges[a][position[a] + 1] if a != axis else edges[a][position[a]] for a in range(3)], dtype=np.float64
    )
    normal = 2 - axis  # xyz index of the face normal
    u, v = (normal + 1) % 3, (normal + 2) % 3  # (u, v, normal) is a right-handed frame
    lo_xyz, hi_xyz = box.bbox_min + lo[::-1] * box.voxel_size, box.bbox_min + hi[::-1] * box.voxel_size
    corners = np.repeat(lo_xyz[None], 4, axis=0)
    corners[1, u] = corners[2, u] = hi_xyz[u]
    corners[2, v] = corners[3, v] = hi_xyz[v]
    return corners


def _face_mesh(mi, name: str, quads: np.ndarray, interior, exterior):
    """One ``null`` triangle mesh of ``quads (Q, 4, 3)`` (two triangles each) with the given media."""
    props = mi.Properties()
    props["bsdf"] = mi.load_dict({"type": "null"})
    if interior is not None:
        props["interior"] = interior
    if exterior is not None:
        props["exterior"] = exterior
    count = len(quads)
    mesh = mi.Mesh(name, 4 * count, 2 * count, props=props)
    base = 4 * np.arange(count, dtype=np.uint32)[:, None]
    faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]], axis=1).reshape(-1, 3)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(quads.reshape(-1).astype(np.float32))
    params["faces"] = mi.UInt32(faces.reshape(-1).astype(np.uint32))
    params.update()
    return mesh
