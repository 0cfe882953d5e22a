"""A VDB frame as a sequence needs it: the density, the grids a DCC's shaders read beside it
(passengers) and its velocity, found by name and resampled onto the density's voxels in voxels per frame."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .vdb import VdbGrid, choose_grid, existing_file, read_vdb_grids, vdb_info
from .vdb_layout import ALBEDO_GRID, DENSITY_GRID, VdbTransform, shape3

# ----------------------------------------------------------------------------- passengers
PASSENGER_GRIDS = ("temperature", "flame", "heat", "color", "Cd")
"""Grids of a source file that a DCC's shaders read beside its density (a fire's temperature and flame,
Mantaflow's heat, a smoke's colour: Blender's ``color``, Houdini's ``Cd``): carried into the ``volume.vdb``
mistyle writes, so an artist's fire shader still finds them. Their values are not stylized."""
SOURCE_PREFIX = "source_"
"""A passenger named like a grid mistyle writes itself (the source's own ``Cd``) is written with this prefix."""


def passenger_grids(path, density_grid: str | None = None) -> tuple[dict, dict]:
    """The grids of ``PASSENGER_GRIDS`` that the ``.vdb`` file ``path`` holds, other than its density grid
    (``choose_grid``'s for ``density_grid``), as read. Returns ``(grids, skipped)``: ``{name: VdbGrid}``,
    and ``{name: reason}`` for a grid left out because it holds NaN or infinite values. An empty grid (no
    active voxel) is left out silently (a shader reads zero where a grid is missing, as where it is
    empty), and so is a grid of a type mistyle does not read (``vdb_info`` lists them)."""
    path, scan = existing_file(path)
    grids = scan["grids"] if scan["grids"] is not None else vdb_info(path)["grids"]
    density = choose_grid(path, scan, density_grid)["name"] if scan["grids"] is not None else density_grid
    counts = {g["name"]: g.get("active_voxel_count", g.get("metadata", {}).get("file_voxel_count")) for g in grids}
    names = [
        g["name"]
        for g in grids
        if g["name"] in PASSENGER_GRIDS and g["readable"] and g["name"] != density and counts[g["name"]] != 0
    ]
    if not names:
        return {}, {}
    # The converter reads a main grid and others: a passenger known to hold voxels is the main one, so the
    # density (read already, when the frame was loaded) is not read again.
    main = next((name for name in names if counts[name]), None)
    if main is None:
        _, read = read_vdb_grids(path, density, names)
    else:
        first, rest = read_vdb_grids(path, main, [name for name in names if name != main])
        read = [first, *rest]
        names = [main, *(name for name in names if name != main)]
    found, skipped = {}, {}
    for name, grid in zip(names, read):
        if grid is None:
            continue
        if not np.all(np.isfinite(grid.array)):
            skipped[name] = f"{int(np.count_nonzero(~np.isfinite(grid.array)))} NaN or infinite value(s)"
            continue
        found[name] = grid
    return found, skipped


def passengers_at(grids: dict, target: VdbTransform, shape_zyx) -> dict:
    """``passenger_grids``' grids sampled at the voxel centres of a ``(Z, Y, X)`` array placed by ``target``
    (the density as mistyle writes it: turned and padded, ``io.load_density_frames``), keyed by the name
    they are written under (``SOURCE_PREFIX`` before a name mistyle writes itself): a scalar grid as
    ``(Z, Y, X)``, a colour as ``(Z, Y, X, 3)``, zero outside the grid's own box."""
    shape = shape3(shape_zyx)
    return {
        (SOURCE_PREFIX + name if name in (DENSITY_GRID, ALBEDO_GRID) else name): _resampled(
            grid.array, grid.transform, target, shape
        )
        for name, grid in grids.items()
    }


# ----------------------------------------------------------------------------- velocities
VELOCITY_GRIDS = ("velocity", "vel", "v")
"""The names a velocity grid goes by, looked for in this order: Blender's, Houdini's, and the short one."""
_COMPONENT_SUFFIXES = ((".x", ".y", ".z"), ("_x", "_y", "_z"))  # a velocity kept as three float grids (Houdini)
DEFAULT_FPS = 24.0
"""Frames per second assumed where neither the caller nor the file says: Blender's and Houdini's default."""
FPS_KEYS = ("fps", "frame_rate", "frames_per_second")  # file metadata that may say it
MANTAFLOW_KEY = "file_base_resolution"
"""Grid metadata that Mantaflow, Blender's fluid solver, writes on every grid of its cache (its
``META_BASE_RES``, extern/mantaflow/preprocessed/fileio/iovdb.cpp); OpenVDB itself never does."""
MANTAFLOW_TIME_PER_SECOND = 2.5
"""Mantaflow's velocities are in its solver's units: cells per solver time unit. Blender lets one frame
last ``0.1 * (25 / fps) * time_scale`` of them (``frame_length`` in blenkernel's fluid.cc, the comment
'dt = 0.1 is at 25fps'), so a second is 2.5 solver time units at the domain's default Time Scale of 1.
The file records neither the frame rate nor the time scale."""


@dataclass(frozen=True)
class VelocitySource:
    """Where a ``.vdb`` file keeps its velocity and what its values mean (``find_velocity``)."""

    file: str
    grids: tuple[str, ...]  # one vec3s grid, or three float grids (x, y, z)
    staggered: bool  # a vec3s grid of class 'staggered' (a MAC grid): component a on the lower face along axis a
    units: str  # 'world' (world units/s), 'index' (the grid's voxels/s: is_local_space) or 'mantaflow'
    fps: float
    fps_from: str  # where ``fps`` comes from, in words

    @property
    def per_frame(self) -> float:
        """The factor from the file's time unit to one frame."""
        return (MANTAFLOW_TIME_PER_SECOND if self.units == "mantaflow" else 1.0) / self.fps

    def describe(self) -> str:
        """One line for the user: the grid, the units read and what was assumed."""
        name = f"grid '{self.grids[0]}'" if len(self.grids) == 1 else "grids " + ", ".join(f"'{g}'" for g in self.grids)
        staggered = " (staggered: faces averaged to cell centres)" if self.staggered else ""
        if self.units == "mantaflow":
            units = (
                "Blender Mantaflow's solver units, cells per solver time unit, 2.5 of which make a second at the "
                "domain's Time Scale 1 (assumed: the cache does not record it)"
            )
        elif self.units == "index":
            units = "voxels per second (the grid says is_local_space)"
        else:
            units = "world units per second"
        return f"velocity from {name}{staggered}, in {units}, at {self.fps:g} fps ({self.fps_from})"


def find_velocity(path, scan: dict, name: str | None = None, fps: float | None = None) -> VelocitySource | None:
    """The velocity grid(s) of a ``.vdb`` file (``scan``: ``check_vdb_layout``'s), or None.

    ``name``: the grid to use, a vec3s grid or the base name of three float grids ``NAME.x``/``.y``/``.z``
    (or ``_x``...); ``ValueError`` naming the file and listing its grids when there is none. None: the
    first of ``VELOCITY_GRIDS`` that the file has, else None. Units: a grid written by Mantaflow (it
    carries ``MANTAFLOW_KEY``) is in Mantaflow's solver units (``MANTAFLOW_TIME_PER_SECOND``); one whose
    metadata says ``is_local_space`` in its own voxels per second; any other in world units per second,
    OpenVDB's convention for vectors and what Houdini's 'vel' and Blender's volume objects (Velocity Unit
    'Second', the default) use. ``fps``: frames per second, else the file's metadata (``FPS_KEYS``), else
    ``DEFAULT_FPS``.
    """
    grids = scan.get("grids")
    if grids is None:  # a file written to a stream: no grid list without the binding, so no velocity
        return None
    by_name = {}
    for grid in grids:
        by_name.setdefault(grid["name"], grid)
    chosen = None
    for candidate in [name] if name else VELOCITY_GRIDS:
        grid = by_name.get(candidate)
        if grid is not None and grid["type"] == "vec3s":
            chosen = (candidate,)
            break
        for suffixes in _COMPONENT_SUFFIXES:
            parts = [by_name.get(candidate + suffix) for suffix in suffixes]
            if all(part is not None and part["type"] == "float" for part in parts):
                chosen = tuple(candidate + suffix for suffix in suffixes)
                break
        if chosen:
            break
    if chosen is None:
        if not name:
            return None
        held = ", ".join(f"'{g['name']}' ({g['type']})" for g in grids) or "no grids"
        raise ValueError(
            f"{path} has no velocity grid '{name}' (a vec3s grid, or float grids '{name}.x', '{name}.y', "
            f"'{name}.z'); it holds {held}. Name the files' velocity grid, or read them without velocities "
            "(velocity_grid='')."
        )
    first = by_name[chosen[0]]
    metadata = first.get("metadata", {})
    if len(chosen) == 1 and MANTAFLOW_KEY in metadata:
        units = "mantaflow"
    elif metadata.get("is_local_space") is True:
        units = "index"
    else:
        units = "world"
    if fps is not None:
        fps_from = "given"
    else:
        recorded = {key: scan["file_metadata"].get(key) for key in FPS_KEYS}
        found = [(k, v) for k, v in recorded.items() if _positive_number(v)]
        fps, fps_from = (
            (float(found[0][1]), f"the file's '{found[0][0]}' metadata")
            if found
            else (DEFAULT_FPS, "assumed: the file records no frame rate")
        )
    if not _positive_number(fps):
        raise ValueError(f"Frames per second must be a positive number, got {fps!r}.")
    staggered = len(chosen) == 1 and first["class"] == "staggered"
    return VelocitySource(os.fspath(path), chosen, staggered, units, float(fps), fps_from)


def _positive_number(value) -> bool:
    return (
        isinstance(value, (int, float, np.number))
        and not isinstance(value, bool)
        and bool(np.isfinite(value))
        and value > 0
    )


class VdbVelocity(NamedTuple):
    """A file's velocity as read (``read_vdb_frame``): its grids as they are, sampled where asked (``at``)."""

    source: VelocitySource
    grids: list  # a VdbGrid per name of ``source.grids``; None for an empty one (no motion)

    def at(self, transform: VdbTransform, shape_zyx) -> np.ndarray:
        """The world displacement of one frame, ``(Z, Y, X, 3)`` float32 world-axis components, at the
        voxel centres of a ``(Z, Y, X)`` array placed by ``transform``: a staggered grid's faces averaged
        to cell centres, copied where the grids share the array's lattice, trilinear where they do not
        (another resolution), zero where the velocity grid has no voxel."""
        return _velocity_per_frame(self.source, self.grids, transform, shape_zyx)


class VdbFrame(NamedTuple):
    """``read_vdb_frame``'s result."""

    density: VdbGrid
    velocity: VdbVelocity | None


def read_vdb_frame(
    path, grid: str | None = None, velocity_grid: str | None = None, fps: float | None = None
) -> VdbFrame:
    """A frame of a sequence: the density grid (``read_vdb_grid``) and the file's velocity grid(s), read
    in one run of the converter.

    The velocity (``find_velocity``: ``velocity_grid``, else the first of ``VELOCITY_GRIDS``; ``''``:
    none) is kept as read, on its own box, and sampled later with ``VdbVelocity.at`` wherever the caller
    places the frame: a sequence's frames share the union of their boxes, and a semi-Lagrangian warp
    reads the velocity where the smoke arrives, beyond the box of the frame's own smoke. ``world_to_index``
    then gives the voxels per frame that ``mistyle.warp`` uses.

    Raises:
        ValueError: as ``read_vdb_grid``; a ``velocity_grid`` the file does not have; non-finite velocities.
    """
    path, scan = existing_file(path)
    source = find_velocity(path, scan, velocity_grid, fps) if velocity_grid != "" else None
    density, extra = read_vdb_grids(path, grid, source.grids if source else ())
    if source is None:
        return VdbFrame(density, None)
    for name, read in zip(source.grids, extra):
        if read is not None and not np.all(np.isfinite(read.array)):
            bad = int(np.count_nonzero(~np.isfinite(read.array)))
            raise ValueError(
                f"Grid '{name}' of {path} holds {bad} NaN or infinite velocity value(s); export the velocity "
                "again, or read the frames without velocities (velocity_grid='')."
            )
    return VdbFrame(density, VdbVelocity(source, extra))


def world_to_index(vectors: np.ndarray, transform: VdbTransform) -> np.ndarray:
    """World vectors ``(..., 3)`` as index steps of ``transform`` (``(x, y, z)`` = along ``i, j, k``, the
    array's last, middle and first axes): a world displacement per frame becomes the voxels per frame of
    ``mistyle.warp``, whatever the grid's voxel size, rotation or turn (``upright``)."""
    to_index = np.linalg.inv(transform.matrix[:3, :3]).T.astype(np.float32)
    return np.ascontiguousarray(np.asarray(vectors, np.float32) @ to_index)


def _velocity_per_frame(source: VelocitySource, grids: list, target: VdbTransform, shape_zyx) -> np.ndarray:
    """World displacement per frame ``(Z, Y, X, 3)`` at the centres of a ``(Z, Y, X)`` array placed by
    ``target``, from the velocity grids of ``source`` (None for an empty one: no motion)."""
    shape = shape3(shape_zyx)
    present = [grid for grid in grids if grid is not None]
    if not present:
        return np.zeros(shape + (3,), np.float32)
    if len(grids) == 1:
        values, transform = present[0].array, present[0].transform
        if source.staggered:
            values, transform = _cell_centred(values, transform)
        sampled = _resampled(values, transform, target, shape)
    else:
        sampled = np.stack(
            [
                np.zeros(shape, np.float32) if g is None else _resampled(g.array, g.transform, target, shape)
                for g in grids
            ],
            axis=-1,
        )
    # float32 throughout: a sequence's union box can hold many millions of voxels, three values each.
    if source.units != "world":  # index steps of the velocity grid (Mantaflow's cells): to world vectors
        sampled = sampled @ present[0].transform.matrix[:3, :3].T.astype(np.float32)
    sampled *= np.float32(source.per_frame)
    return sampled


def _cell_centred(values: np.ndarray, transform: VdbTransform) -> tuple[np.ndarray, VdbTransform]:
    """A staggered (MAC) vec3 grid's values at its cell centres, on a box one voxel larger on every side.

    OpenVDB's staggered convention, which Mantaflow's MAC grids follow: component a of voxel n sits on the
    voxel's lower face along index axis a (x at ``(i - 1/2, j, k)``), so the centre of voxel n has the mean
    of the faces of n and n + 1. Outside the read box the grid holds its background, zero."""
    padded = np.pad(values, ((1, 1), (1, 1), (1, 1), (0, 0)))
    centred = np.empty_like(padded)
    for component, axis in ((0, 2), (1, 1), (2, 0)):  # x runs along the array's last axis
        face = padded[..., component]
        upper = np.zeros_like(face)
        take, put = [slice(None)] * 3, [slice(None)] * 3
        take[axis], put[axis] = slice(1, None), slice(None, -1)
        upper[tuple(put)] = face[tuple(take)]
        centred[..., component] = 0.5 * (face + upper)
    return centred, VdbTransform(transform.matrix, tuple(np.subtract(transform.index_min, 1)))


_RESAMPLE_CHUNK = 1 << 20  # target voxels per step of the trilinear sampling: bounds its temporary arrays


def _resampled(values: np.ndarray, transform: VdbTransform, target: VdbTransform, shape_zyx) -> np.ndarray:
    """``values`` (``(Z', Y', X')`` or ``(Z', Y', X', C)`` at the voxel centres of ``transform``, zero
    outside their box) at the voxel centres of a ``(Z, Y, X)`` array placed by ``target``: copied when the
    two share a lattice (the grids of one file, as a rule), else trilinear (a grid at another resolution)."""
    shape = shape3(shape_zyx)
    channels = values.shape[3:]
    source = values.reshape(values.shape[:3] + (-1,))
    linear = transform.matrix[:3, :3]
    step = np.linalg.solve(linear, target.matrix[:3, :3])  # source index steps per target index step
    corner = target.index_to_world(np.asarray(target.index_min, np.float64))
    start = np.linalg.solve(linear, corner - transform.matrix[:3, 3]) - np.asarray(transform.index_min)
    size = np.array(source.shape[:3][::-1])  # (x, y, z)
    out = np.zeros(shape + (source.shape[3],), np.float32)
    if np.allclose(step, np.eye(3), rtol=0.0, atol=1e-6) and np.allclose(start, np.round(start), rtol=0.0, atol=1e-6):
        offset = np.round(start).astype(np.int64)  # source voxel = target voxel + offset, (x, y, z)
        low = np.maximum(0, -offset)
        high = np.minimum(np.array(shape[::-1]), size - offset)
        if np.all(high > low):
            out[low[2] : high[2], low[1] : high[1], low[0] : high[0]] = source[
                low[2] + offset[2] : high[2] + offset[2],
                low[1] + offset[1] : high[1] + offset[1],
                low[0] + offset[0] : high[0] + offset[0],
            ]
        return out.reshape(shape + channels)
    flat = source.reshape(-1, source.shape[3])
    count = int(np.prod(shape))
    target_out = out.reshape(-1, source.shape[3])
    for begin in range(0, count, _RESAMPLE_CHUNK):
        number = np.arange(begin, min(count, begin + _RESAMPLE_CHUNK))
        z, rest = np.divmod(number, shape[1] * shape[2])
        y, x = np.divmod(rest, shape[2])
        where = start + np.stack([x, y, z], axis=-1) @ step.T  # (N, 3) in the source's local (x, y, z)
        base = np.floor(where).astype(np.int64)
        frac = where - base
        total = np.zeros((len(number), source.shape[3]), np.float64)
        for bits in np.ndindex(2, 2, 2):
            voxel = base + bits
            inside = np.all((voxel >= 0) & (voxel < size), axis=1)
            weight = np.prod(np.where(bits, frac, 1.0 - frac), axis=1) * inside
            voxel = np.clip(voxel, 0, size - 1)
            total += weight[:, None] * flat[(voxel[:, 2] * size[1] + voxel[:, 1]) * size[0] + voxel[:, 0]]
        target_out[number] = total
    return out.reshape(shape + channels)
