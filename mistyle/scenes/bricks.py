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

Every level's medium spans the whole box (its grid is zero outside its bricks) and all levels share
one albedo grid, and every pair of the regions present (vacuum and the levels) has its face mesh, a
degenerate one where they do not touch, plus one mesh of two degenerate triangles at the box's corners
that holds the scene's bounds at the box. Memory: ``levels`` density grids of the box and one albedo
grid, about what the crops held (bundled smoke, 64^3: the four crops summed to 1.6 boxes, each with
its density and albedo: 6.5 box-sized float grids then, 7 now).

So the scene's structure, and every scalar that Mitsuba bakes into the kernel as a literal (a
medium's bounding box and grid transform, the scene's bounding sphere, the media each mesh names, how
many shapes and media the calls dispatch over), depends on the grid's shape and on which levels are
present (``present_levels``) alone. A new frame of the same structure is the same kernel with new
data (``update_bricked_media``: grids and face meshes through ``mi.traverse``), compiled once for a
sequence (``pathtrace.SceneCache``). Cropping each level to its bricks, as this module did before,
baked each frame's crop into the kernel: one compilation per frame.

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
from ..volume import validate_albedo
from .box import MediumBox
from .medium import grid_volume, heterogeneous_medium

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


BOUNDS_MESH = "brick_faces_vacuum_vacuum"
"""The mesh of two degenerate triangles at the box's corners: it keeps the scene's bounding box (whose
sphere Mitsuba bakes into the kernel, e.g. the constant emitter's) the medium box whatever the faces;
named as a face mesh with vacuum on both sides (no media)."""


def present_levels(level: np.ndarray) -> tuple[int, ...]:
    """The majorant levels that hold bricks (``brick_levels``'s ``level``), ascending: with the grid's
    shape, all that the structure of a bricked scene depends on."""
    return tuple(int(k) for k in np.unique(level[level >= 0]))


def region_pairs(present: tuple[int, ...]) -> list[tuple[int, int]]:
    """Every ``(below, above)`` pair of different regions among vacuum (-1) and the ``present`` levels:
    the face meshes of a bricked scene, in a fixed order."""
    regions = (-1, *present)
    return [(inner, outer) for inner in regions for outer in regions if inner != outer]


def face_mesh_name(inner: int, outer: int) -> str:
    return f"brick_faces_{_region_name(inner)}_{_region_name(outer)}"


def bricked_media(
    density: np.ndarray,
    density_scale: float,
    albedo: np.ndarray,
    brick: int = DEFAULT_BRICK,
    levels: int = DEFAULT_LEVELS,
    split: tuple[np.ndarray, list[np.ndarray]] | None = None,
) -> dict:
    """Scene entries (``null`` face meshes carrying the media) that replace ``medium.medium_cube``.

    Args:
        density: ``(Z, Y, X)`` >= 0; albedo: ``(Z, Y, X, 3)``; density_scale: as ``heterogeneous_medium``.
        brick: voxels per brick side.
        levels: number of majorant levels (media); see ``brick_levels``.
        split: ``brick_levels(density, brick, levels)`` when the caller has it already.

    Returns:
        a dict to merge into a scene dictionary, already instantiated: one ``brick_faces_A_B`` mesh per
        pair of regions (``region_pairs``; ``A``, ``B``: level or ``vacuum``), degenerate where they
        do not touch, carrying the media of ``A`` (interior) and ``B`` (exterior), and ``BOUNDS_MESH``.
    """
    mi = require_variant()
    box = MediumBox(density.shape)
    level, edges = brick_levels(density, brick, levels) if split is None else split
    # One albedo grid for every level: inside a level's bricks the whole grid gives the same field.
    shared = mi.load_dict(grid_volume(validate_albedo(albedo, density.shape), box.unit_to_world_matrix()))
    media = {
        k: mi.load_dict(heterogeneous_medium(grid, density_scale, shared))
        for k, grid in level_densities(density, level, edges).items()
    }
    quads = face_quads(box, level, edges)
    entries = {}
    for inner, outer in region_pairs(present_levels(level)):
        name = face_mesh_name(inner, outer)
        entries[name] = _face_mesh(mi, name, quads[inner, outer], media.get(inner), media.get(outer))
    entries[BOUNDS_MESH] = _face_mesh(mi, BOUNDS_MESH, _bounds_quads(box), None, None)
    return entries


def update_bricked_media(
    params,
    density: np.ndarray,
    albedo: np.ndarray,
    brick: int = DEFAULT_BRICK,
    levels: int = DEFAULT_LEVELS,
    split: tuple[np.ndarray, list[np.ndarray]] | None = None,
) -> None:
    """Set a new frame's grids and face meshes in the parameters (``mi.traverse(scene)``, not yet
    updated) of a scene holding ``bricked_media`` of a frame of the same shape and ``present_levels``;
    the caller checks both. The scene then renders as one built from this frame (bit for bit: the same
    objects in the same order, the same data), without compiling a kernel anew.

    Args:
        density: ``(Z, Y, X)``; albedo: ``(Z, Y, X, 3)`` in [0, 1]; brick, levels, split: as ``bricked_media``.
    """
    mi = require_variant()
    box = MediumBox(density.shape)
    level, edges = brick_levels(density, brick, levels) if split is None else split
    grids = level_densities(density, level, edges)
    quads = face_quads(box, level, edges)
    for key in params.keys():
        # A shared object is listed once, under the first mesh that names it: the key's mesh and side
        # (interior: the name's first region, exterior: its second) tell which level's medium it is.
        parts = key.split(".")  # e.g. brick_faces_0_vacuum.interior_medium.sigma_t.data
        if parts[2:] == ["sigma_t", "data"]:
            inner, outer = parts[0].split("_")[-2:]
            k = int(inner if parts[1] == "interior_medium" else outer)
            params[key] = mi.TensorXf(grids[k][..., None])
        elif parts[2:] == ["albedo", "data"]:
            params[key] = mi.TensorXf(validate_albedo(albedo, density.shape))
    for inner, outer in region_pairs(present_levels(level)):
        vertices, faces = _mesh_buffers(quads[inner, outer])
        name = face_mesh_name(inner, outer)
        params[f"{name}.vertex_positions"] = vertices
        params[f"{name}.faces"] = faces


def level_densities(density: np.ndarray, level: np.ndarray, edges: list[np.ndarray]) -> dict[int, np.ndarray]:
    """Each present level's density grid ``(Z, Y, X)`` float32: ``density`` in its bricks and their halos,
    zero elsewhere (its maximum is the level's majorant), over the whole box so that its transform and
    bounding box (literals in the kernel) are the box's whatever the frame."""
    # Each voxel's brick level, then a level's bricks grown by the one-voxel halo (a 3x3x3 maximum,
    # separable: one axis at a time): the union of its bricks' windows, each a brick and one voxel
    # more on every side, clipped to the grid.
    brick_of = [np.searchsorted(bounds, np.arange(n), side="right") - 1 for bounds, n in zip(edges, density.shape)]
    voxel_level = level[np.ix_(*brick_of)]
    grids = {}
    for k in present_levels(level):
        mask = voxel_level == k
        for axis in range(3):
            grown = mask.copy()
            ahead = [slice(None)] * 3
            behind = [slice(None)] * 3
            ahead[axis], behind[axis] = slice(1, None), slice(None, -1)
            grown[tuple(behind)] |= mask[tuple(ahead)]
            grown[tuple(ahead)] |= mask[tuple(behind)]
            mask = grown
        grids[k] = np.where(mask, density, 0.0).astype(np.float32)
    return grids


def face_quads(box: MediumBox, level: np.ndarray, edges: list[np.ndarray]) -> dict[tuple[int, int], np.ndarray]:
    """The faces between regions: ``(below, above) -> corners (Q, 4, 3)`` for every pair of
    ``region_pairs`` (one degenerate quad where the two do not touch).

    Faces perpendicular to each axis where the media on the two sides differ, one mesh per pair
    (below, above). Each triangle's geometric normal points to +axis, so the region above is the
    mesh's exterior (Mitsuba: the target medium of a direction with dot(n, d) > 0).
    Meshes, not ``rectangle`` shapes: through rectangles, volpath renders a thin medium ~1% too
    bright (measured against the box's ``cube`` and against meshes; tests/test_bricks.py).
    """
    quads: dict[tuple[int, int], list[np.ndarray]] = {pair: [] for pair in region_pairs(present_levels(level))}
    for axis in range(3):  # 0: z, 1: y, 2: x (grid order)
        padded = np.pad(level, [(1, 1) if a == axis else (0, 0) for a in range(3)], constant_values=-1)
        below = np.take(padded, np.arange(0, padded.shape[axis] - 1), axis=axis)
        above = np.take(padded, np.arange(1, padded.shape[axis]), axis=axis)
        for position in zip(*np.nonzero(below != above)):
            pair = (int(below[position]), int(above[position]))
            quads[pair].append(_quad(box, edges, axis, position))
    # A pair that does not touch keeps one degenerate quad at the box's corner (no area, so no ray meets
    # it but with probability zero): a mesh without faces makes Mitsuba's traced calls gather from an
    # empty buffer, and the mesh must exist for the next frame.
    nothing = _bounds_quads(box)[:1]
    return {pair: np.stack(corners) if corners else nothing for pair, corners in quads.items()}


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


def _bounds_quads(box: MediumBox) -> np.ndarray:
    """Two degenerate quads ``(2, 4, 3)``, each four times one corner of the box: bounds, no area."""
    return np.stack([np.repeat(box.bbox_min[None], 4, axis=0), np.repeat(box.bbox_max[None], 4, axis=0)])


def _mesh_buffers(quads: np.ndarray):
    """The flat ``mi.Float`` vertex positions and ``mi.UInt32`` faces of ``quads (Q, 4, 3)``, two
    triangles each (both counter-clockwise seen from the quad's normal)."""
    mi = require_variant()
    count = len(quads)
    base = 4 * np.arange(count, dtype=np.uint32)[:, None]
    faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]], axis=1).reshape(-1, 3)
    return (
        mi.Float(np.asarray(quads, dtype=np.float32).reshape(-1)),
        mi.UInt32(faces.reshape(-1).astype(np.uint32)),
    )


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
    params = mi.traverse(mesh)
    params["vertex_positions"], params["faces"] = _mesh_buffers(quads)
    params.update()
    return mesh
