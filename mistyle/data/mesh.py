"""Closed meshes -> density grids, by ray parity with Mitsuba's own ray tracer.

A point is inside a closed (watertight) mesh when a ray from it crosses the surface an odd
number of times. Every sample point shoots rays along three fixed, slightly skewed directions
(so no ray runs exactly along an edge or through a vertex) and the majority vote decides. With
``supersample = s`` each voxel averages ``s^3`` points, which gives a soft, anti-aliased edge.

The mesh is centred in the medium box and scaled uniformly so that the longest side of its
bounding box spans ``1 - 2 * margin`` of the box; the grid keeps the mesh's aspect ratio.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from ..files import atomic_write_bytes

_DIRECTIONS = np.array([[1.0, 0.0123, 0.0271], [0.0191, 1.0, -0.0137], [-0.0229, 0.0167, 1.0]])


def icosphere(subdivisions: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A unit icosphere: vertices ``(V, 3)`` float64 and outward-wound triangles ``(F, 3)`` int."""
    t = (1.0 + 5.0**0.5) / 2.0
    vertices = [
        (-1, t, 0),
        (1, t, 0),
        (-1, -t, 0),
        (1, -t, 0),
        (0, -1, t),
        (0, 1, t),
        (0, -1, -t),
        (0, 1, -t),
        (t, 0, -1),
        (t, 0, 1),
        (-t, 0, -1),
        (-t, 0, 1),
    ]
    faces = [
        (0, 11, 5),
        (0, 5, 1),
        (0, 1, 7),
        (0, 7, 10),
        (0, 10, 11),
        (1, 5, 9),
        (5, 11, 4),
        (11, 10, 2),
        (10, 7, 6),
        (7, 1, 8),
        (3, 9, 4),
        (3, 4, 2),
        (3, 2, 6),
        (3, 6, 8),
        (3, 8, 9),
        (4, 9, 5),
        (2, 4, 11),
        (6, 2, 10),
        (8, 6, 7),
        (9, 8, 1),
    ]
    vertices = [np.array(v, dtype=np.float64) / np.linalg.norm(v) for v in vertices]
    for _ in range(subdivisions):
        midpoint_cache: dict[tuple[int, int], int] = {}

        def midpoint(a: int, b: int, cache: dict = midpoint_cache) -> int:
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = vertices[a] + vertices[b]
                vertices.append(m / np.linalg.norm(m))
                cache[key] = len(vertices) - 1
            return cache[key]

        refined = []
        for a, b, c in faces:
            ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
            refined += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = refined
    return np.array(vertices), np.array(faces, dtype=np.int64)


def displaced_icosphere(seed: int = 0, subdivisions: int = 4, amplitude: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
    """A rock-like closed mesh: an icosphere whose vertices move along their normals by a random
    sum of low-order waves (up to ``amplitude`` of the radius), squashed to 1 x 0.8 x 0.7."""
    vertices, faces = icosphere(subdivisions)
    rng = np.random.default_rng(seed)
    offset = np.zeros(len(vertices))
    for frequency in (1.5, 3.0, 6.0):
        directions = rng.normal(size=(3, 3))
        for direction, phase in zip(directions, rng.uniform(0, 2 * np.pi, 3)):
            offset += np.sin(frequency * vertices @ direction + phase) / frequency
    offset *= amplitude / np.abs(offset).max()
    return vertices * (1.0 + offset)[:, None] * np.array([1.0, 0.8, 0.7]), faces


def write_ply(path, vertices: np.ndarray, faces: np.ndarray) -> Path:
    """Write a binary little-endian PLY triangle mesh, atomically."""
    vertices = np.asarray(vertices, dtype="<f4")
    faces = np.asarray(faces, dtype="<i4")
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    rows = b"".join(struct.pack("<B3i", 3, *face) for face in faces.tolist())
    return atomic_write_bytes(path, header + vertices.tobytes() + rows)


def load_mesh(path) -> tuple[np.ndarray, np.ndarray]:
    """Read a ``.ply`` or ``.obj`` triangle mesh with Mitsuba; returns vertices ``(V,3)``, faces ``(F,3)``."""
    from ..backend import active_variant

    mi = active_variant()
    path = Path(path)
    kind = {".ply": "ply", ".obj": "obj"}.get(path.suffix.lower())
    if kind is None:
        raise ValueError(f"Unsupported mesh {path}: use a .ply or .obj file.")
    if not path.is_file():
        raise ValueError(f"Mesh file {path} does not exist.")
    try:
        mesh = mi.load_dict({"type": kind, "filename": str(path), "face_normals": True})
    except Exception as error:  # Mitsuba raises RuntimeError with its own parser message
        raise ValueError(f"Cannot read the mesh {path}: {error}") from error
    params = mi.traverse(mesh)
    vertices = np.asarray(params["vertex_positions"], dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(params["faces"], dtype=np.int64).reshape(-1, 3)
    return vertices, faces


def check_closed(faces: np.ndarray, name: str = "mesh") -> None:
    """Raise ``ValueError`` unless every edge is shared by exactly two triangles (watertight)."""
    faces = np.asarray(faces)
    if faces.size == 0:
        raise ValueError(f"The {name} has no triangles; voxelization needs a closed surface.")
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    open_edges = int((counts != 2).sum())
    if open_edges:
        raise ValueError(
            f"The {name} is not watertight: {open_edges} edges are not shared by exactly two triangles. "
            "Close the holes (e.g. with a hole-filling or remeshing tool) before voxelizing."
        )


def voxelize(
    vertices: np.ndarray, faces: np.ndarray, resolution: int = 64, margin: float = 0.05, supersample: int = 1
) -> np.ndarray:
    """Density ``(Z, Y, X)`` float32 in [0, 1]: 1 inside the closed mesh, 0 outside.

    Args:
        resolution: voxels along the longest side of the mesh's bounding box (plus margins).
        margin: empty border on each side, as a fraction of the box.
        supersample: ``s^3`` parity tests per voxel, averaged (``1``: a binary grid).
    """
    import drjit as dr

    from ..backend import active_variant

    mi = active_variant()

    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    check_closed(faces)
    if resolution < 2 or not 0 <= margin < 0.5 or supersample < 1:
        raise ValueError(
            f"Need resolution >= 2, margin in [0, 0.5) and supersample >= 1; got {resolution}, {margin}, {supersample}."
        )
    placed, box = fit_to_box(vertices, resolution, margin)

    mesh = mi.Mesh("voxelized", len(placed), len(faces))
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(placed.astype(np.float32).ravel())
    params["faces"] = mi.UInt32(faces.astype(np.uint32).ravel())
    params.update()
    scene = mi.load_dict({"type": "scene", "mesh": mesh})

    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    inside = np.zeros(box.shape_zyx, dtype=np.float64)
    centres = box.voxel_centres()
    for oz in offsets:
        for oy in offsets:
            for ox in offsets:
                points = (centres + np.array([ox, oy, oz]) * box.voxel_size).reshape(-1, 3)
                votes = sum(_odd_crossings(mi, dr, scene, points, d / np.linalg.norm(d)) for d in _DIRECTIONS)
                inside += (votes >= 2).reshape(box.shape_zyx)
    return (inside / supersample**3).astype(np.float32)


def fit_to_box(vertices: np.ndarray, resolution: int, margin: float):
    """Centre and scale vertices into a medium box; returns ``(placed (V, 3), MediumBox)``.

    The longest side of the vertices' bounding box spans ``1 - 2 * margin``; the grid has
    ``resolution`` voxels along that side and keeps the aspect ratio.
    """
    from ..scenes.box import MediumBox

    low, high = vertices.min(axis=0), vertices.max(axis=0)
    extent = high - low
    if extent.max() <= 0:
        raise ValueError("The mesh has no extent (all vertices coincide).")
    scale = (1.0 - 2.0 * margin) / extent.max()
    placed = (vertices - 0.5 * (low + high)) * scale
    shape_xyz = np.maximum(1, np.ceil((extent * scale + 2 * margin) * resolution - 1e-9)).astype(int)
    return placed, MediumBox((int(shape_xyz[2]), int(shape_xyz[1]), int(shape_xyz[0])))


def _odd_crossings(mi, dr, scene, points: np.ndarray, direction: np.ndarray) -> np.ndarray:
    origin = mi.Point3f(*(mi.Float(points[:, i].astype(np.float32)) for i in range(3)))
    ray = mi.Ray3f(origin, mi.Vector3f(*(float(c) for c in direction)))
    crossings = dr.zeros(mi.UInt32, len(points))
    active = dr.full(mi.Bool, True, len(points))
    for _ in range(256):  # a line crosses a sane mesh far fewer times
        hit = scene.ray_intersect(ray, active)
        active &= hit.is_valid()
        if not dr.any(active):
            break
        crossings += mi.UInt32(active)
        ray = hit.spawn_ray(ray.d)
    return (crossings.numpy() % 2).astype(np.int64)
