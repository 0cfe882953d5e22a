"""Density volumes: Mitsuba ``.vol`` grids, numpy ``.npy``/``.npz`` and OpenVDB files, one frame or a
sequence in one box (``load_density_frames``)."""

from __future__ import annotations

import math
import os
import re
import struct
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..conventions import MAX_GRID_VOXELS
from ..volume import validate_density
from .paths import atomic_output, atomic_write_bytes, check_link

# --- Mitsuba's binary grid format: b"VOL", version 3, encoding 1 (float32), then X, Y, Z, channels
# --- (int32), the bounding box (6 x float32) and the data in [z, y, x, c] order. mi.VolumeGrid
# --- reads and writes the same layout, but cannot be given a bounding box (it always writes the unit
# --- cube), and the medium box is rarely one; tests/test_io.py checks both directions against it.
_VOL_HEADER = struct.Struct("<3sBiiiii6f")


def write_vol(path, grid: np.ndarray, bbox_min=(0.0, 0.0, 0.0), bbox_max=(1.0, 1.0, 1.0)) -> Path:
    """Write a ``(Z, Y, X)`` or ``(Z, Y, X, C)`` grid as a Mitsuba ``.vol`` file, atomically."""
    data = np.asarray(grid, dtype=np.float32)
    if data.ndim == 3:
        data = data[..., None]
    if data.ndim != 4:
        raise ValueError(f".vol grids must be (Z, Y, X) or (Z, Y, X, C), got shape {data.shape}.")
    z, y, x, c = data.shape
    header = _VOL_HEADER.pack(b"VOL", 3, 1, x, y, z, c, *bbox_min, *bbox_max)
    return atomic_write_bytes(path, header + np.ascontiguousarray(data).tobytes())


def read_vol(path) -> np.ndarray:
    """Read a float32 Mitsuba ``.vol`` file; returns ``(Z, Y, X)`` for one channel, else ``(Z, Y, X, C)``.

    The header's sizes are checked against the file's length and ``conventions.MAX_GRID_VOXELS`` before
    the voxels are read."""
    with open(path, "rb") as handle:
        raw = handle.read(_VOL_HEADER.size)
        held = os.fstat(handle.fileno()).st_size - _VOL_HEADER.size
        if raw[:3] != b"VOL":
            raise ValueError(f"{path} is not a Mitsuba .vol file (missing the 'VOL' header).")
        if len(raw) < _VOL_HEADER.size:
            raise ValueError(
                f"{path}: its .vol header is cut short ({len(raw)} of {_VOL_HEADER.size} bytes); the file is "
                "truncated: write it again."
            )
        magic, version, encoding, x, y, z, c, *_bbox = _VOL_HEADER.unpack_from(raw)
        _check_vol_header(path, version, encoding, (x, y, z, c), held)
        data = np.fromfile(handle, dtype="<f4", count=x * y * z * c)
    data = np.asarray(data, dtype=np.float32).reshape(z, y, x, c)
    return data[..., 0] if c == 1 else data


def _check_vol_header(path, version: int, encoding: int, size_xyzc: tuple, held: int) -> None:
    """``ValueError`` unless a ``.vol`` header describes float32 data of exactly the ``held`` bytes after it,
    in a grid of at most ``MAX_GRID_VOXELS``."""
    x, y, z, c = size_xyzc
    if version != 3 or encoding != 1:
        raise ValueError(
            f"{path}: only .vol version 3 with float32 data is supported (got version {version}, encoding {encoding})."
        )
    if min(x, y, z, c) < 1:
        raise ValueError(
            f"{path}: the header gives the grid size {x}x{y}x{z} with {c} channels; every size must be >= 1."
        )
    count = x * y * z * c
    if held != 4 * count:
        raise ValueError(
            f"{path}: header says {x}x{y}x{z}x{c} floats but the file holds {held // 4}; it is truncated or "
            "its header is wrong: write it again."
        )
    if x * y * z > MAX_GRID_VOXELS:
        raise ValueError(
            f"{path} is a {x}x{y}x{z} grid ({x * y * z} voxels); mistyle reads grids of up to {MAX_GRID_VOXELS} "
            f"voxels (conventions.MAX_GRID_VOXELS, {MAX_GRID_VOXELS * 4 >> 30} GiB as float32): crop or downsample it."
        )


DENSITY_SUFFIXES = (".vol", ".vdb", ".npy", ".npz")


class DensityFrames(NamedTuple):
    """``load_density_frames``' result; ``transforms`` only for ``.vdb`` frames (else None)."""

    densities: list  # (Z, Y, X) float32 each
    velocities: list | None  # (Z, Y, X, 3) each, when every frame has one
    names: list  # file stems
    transforms: list | None  # vdb.VdbTransform each: where the grid sits in the file's world
    up: str | None = None  # .vdb frames: the world up axis they were turned to (``load_density_frames``)


def load_density(path, grid: str | None = None) -> np.ndarray:
    """Load and validate a density grid ``(Z, Y, X)`` from a ``.vol``, ``.vdb`` (float grid ``grid``,
    default ``density`` or the only one), ``.npy`` or ``.npz`` (key ``density``) file."""
    return _read_density_file(Path(path), grid)["density"]


def frame_order(path: Path) -> tuple:
    """The sort key of a frame file: its name with each run of digits compared as a number, so that
    ``smoke_2`` comes before ``smoke_10`` (simulators do not all pad frame numbers); the name breaks ties."""
    parts = re.split(r"(\d+)", path.name)
    return tuple(int(part) if index % 2 else part for index, part in enumerate(parts)), path.name


def density_frame_files(path) -> list[Path]:
    """The frame files of a density: the file itself, or a folder's density files in the order of
    their frame numbers (``frame_order``)."""
    path = Path(path)
    if not path.is_dir():
        return [path]
    candidates = sorted((p for p in path.iterdir() if p.suffix.lower() in DENSITY_SUFFIXES), key=frame_order)
    for candidate in candidates:  # a frame left out of a sequence would go unnoticed in the render
        check_link(candidate, "The frame", "restore the frame or remove the link; a sequence renders every frame")
    files = [p for p in candidates if p.is_file()]
    if not files:
        inner = _frames_below(path)
        hint = f"; its subfolder {inner} does (Blender's caches keep their frames in data/): read that" if inner else ""
        raise ValueError(f"The folder {path} holds no {', '.join(DENSITY_SUFFIXES)} density frames{hint}.")
    return files


def _frames_below(path: Path, depth: int = 2) -> Path | None:
    """The first subfolder of ``path``, at most ``depth`` levels down, that holds density files."""
    try:
        folders = sorted(p for p in path.iterdir() if p.is_dir() and not p.name.startswith("."))
    except OSError:
        return None
    for folder in folders:
        try:
            if any(p.suffix.lower() in DENSITY_SUFFIXES and p.is_file() for p in folder.iterdir()):
                return folder
        except OSError:
            continue
    for folder in folders if depth > 1 else ():
        found = _frames_below(folder, depth - 1)
        if found is not None:
            return found
    return None


def load_density_frames(
    path,
    grid: str | None = None,
    up: str | None = None,
    *,
    velocity_grid: str | None = None,
    fps: float | None = None,
    notes: list | None = None,
) -> DensityFrames:
    """Density frames from a file or a folder of frame files (in frame-number order, ``frame_order``).

    Velocities, ``(Z, Y, X, 3)`` per frame in ``mistyle.warp``'s units: voxels per frame, components
    ``(x, y, z)`` along the array's last, middle and first axes, frame t's velocity carrying it towards
    frame t + 1. They are returned only for a sequence of two or more frames in which every frame has
    one; where some frames have one and others do not, none are, and ``notes`` says which frames lack
    it (flicker is then measured unwarped). ``.npz`` frames of ``python -m mistyle.data`` carry theirs
    as the array ``velocity``. ``.vdb`` frames: the grid ``velocity_grid`` (a vec3s grid, or three float
    grids ``NAME.x``/``.y``/``.z``; ``ValueError`` naming the file when one lacks it), else the first of
    ``velocity``, ``vel``, ``v`` that a file has (``vdb.find_velocity``); ``''`` reads none. A file's
    world units per second (OpenVDB's, Houdini's and Blender's volume convention) or Mantaflow's solver
    units (Blender's fluid cache, recognised by its metadata) are turned into voxels of the density per
    frame with the density's transform and ``fps`` (else the file's ``fps`` metadata, else 24, which
    ``notes`` then says); a staggered grid is averaged to cell centres and a grid on another lattice is
    resampled onto the density's voxels (``vdb.read_vdb_frame``). Components turn with the grid (``up``).
    ``.vol``/``.npy``/``.npz`` frames must share one grid size.

    ``.vdb`` frames are placed in one index space (``vdb_frames_in_one_box``): a simulation's smoke grows
    and moves, so each file's active voxels span another box; every frame is padded with zeros to the
    union of those boxes, so that element ``[z, y, x]`` is the same place in the world in every frame,
    and each frame's transform follows (its output VDB lands where the source was).

    ``up``: the world up axis of ``.vdb`` frames (``conventions.UP_AXES``; ``z`` for Blender's). Each grid
    is turned so that the index axis closest to it is the array's Y, which mistyle renders as up, and its
    transform follows (``vdb.upright``: every voxel stays where it was). None: what a file mistyle wrote
    says (``mistyle_up_axis``), else ``y``. Other files are in mistyle's own box, whose up is y.
    """
    path = Path(path)
    notes = [] if notes is None else notes
    files = density_frame_files(path)
    # A single frame has nothing to be warped towards: its velocity would be read for nothing.
    motion = {"velocity_grid": velocity_grid, "fps": fps} if len(files) > 1 and velocity_grid != "" else None
    frames = [_read_density_file(file, grid, up, turn=False, motion=motion) for file in files]
    if len(frames) > 1 and all(frame.get("transform") is not None for frame in frames):
        frames = vdb_frames_in_one_box(files, frames)
    frames = [_turned(frame) for frame in frames]
    shapes = {frame["density"].shape for frame in frames}
    if len(shapes) > 1:
        raise ValueError(
            f"The frames in {path} have different shapes {sorted(shapes)}; a sequence needs one grid size."
        )
    velocities = [frame.get("velocity") for frame in frames]
    lacking = [file.name for file, velocity in zip(files, velocities) if velocity is None]
    if lacking and len(lacking) < len(files):
        shown = ", ".join(lacking[:5]) + (f" and {len(lacking) - 5} more" if len(lacking) > 5 else "")
        notes.append(
            f"{shown} of {path} carr{'ies' if len(lacking) == 1 else 'y'} no velocity, so the sequence is read "
            "without velocities: frames are not warped by their motion, and flicker is measured unwarped"
        )
    elif not lacking and frames[0].get("velocity_source") is not None:
        notes.append(f"{path}: {frames[0]['velocity_source'].describe()}")
    transforms = [frame.get("transform") for frame in frames]
    return DensityFrames(
        [frame["density"] for frame in frames],
        velocities if not lacking else None,
        [file.stem for file in files],
        transforms if all(t is not None for t in transforms) else None,
        frames[0].get("up"),
    )


def vdb_frames_in_one_box(files: list[Path], frames: list[dict]) -> list[dict]:
    """``.vdb`` frames (``_read_density_file(..., turn=False)``: arrays in their files' index order) padded
    with zeros to the union of their index boxes, with transforms that keep every voxel where it was.
    Their velocities are still the grids as read (``"vdb_velocity"``), sampled over the whole union box
    when the frame is turned (``_turned``): the warp reads a frame's velocity where its smoke goes next,
    outside the box of its smoke now, and the file has it there (zero only where its grid has no voxel).

    The union is taken in the first frame's index space. Another frame's index space must be the same
    lattice: the same index-to-world linear part (a simulation keeps its voxel size and orientation) and
    an origin a whole number of voxels away (Blender's adaptive domain moves by whole voxels), else
    ``ValueError`` naming the two files, since mistyle would have to resample. Each returned frame keeps
    its own file's matrix, its ``index_min`` moved to the union's corner, so its output VDB has the
    source's own index coordinates and matrix.
    """
    first = frames[0]["transform"]
    linear, origin = first.matrix[:3, :3], first.matrix[:3, 3]
    scale = float(np.abs(linear).max())
    boxes, shifts = [], []
    for file, frame in zip(files, frames):
        transform = frame["transform"]
        if not np.allclose(transform.matrix[:3, :3], linear, rtol=0.0, atol=1e-9 * scale):
            sizes = [_format_size(t.voxel_size) for t in (first, transform)]
            if sizes[0] != sizes[1]:
                raise ValueError(
                    f"The .vdb frames {files[0].name} and {file.name} have different voxel sizes ({sizes[0]} and "
                    f"{sizes[1]}); frames of one sequence share one voxel size. Resample them onto one grid "
                    "(e.g. Houdini's VDB Resample), or render them separately."
                )
            raise ValueError(
                f"The .vdb frames {files[0].name} and {file.name} are rotated against each other (their "
                "index-to-world matrices differ); frames of one sequence share one grid orientation. Resample "
                "them onto one grid, or render them separately."
            )
        # Where this frame's index origin lies in the first frame's index space: a whole number of voxels.
        shift = np.linalg.solve(linear, transform.matrix[:3, 3] - origin)
        whole = np.round(shift)
        if np.abs(shift - whole).max() > 1e-6:
            raise ValueError(
                f"The .vdb frame {file.name}'s voxels are offset by a fraction of a voxel from {files[0].name}'s "
                f"({np.round(shift - whole, 4).tolist()} voxels along i, j, k); frames of one sequence share one "
                "voxel lattice. Resample them onto one grid, or render them separately."
            )
        shifts.append(whole.astype(np.int64))
        low = np.array(transform.index_min, dtype=np.int64) + shifts[-1]
        boxes.append((low, low + np.array(frame["density"].shape[::-1]) - 1))
    union_low = np.min([low for low, _ in boxes], axis=0)
    union_high = np.max([high for _, high in boxes], axis=0)
    size_xyz = union_high - union_low + 1
    if int(np.prod(size_xyz)) > MAX_GRID_VOXELS:
        raise ValueError(
            f"The .vdb frames from {files[0].name} to {files[-1].name} span {'x'.join(map(str, size_xyz))} "
            f"voxels together (the union of their boxes), more than the {MAX_GRID_VOXELS} mistyle renders "
            "(conventions.MAX_GRID_VOXELS); crop or resample the frames, or split the sequence into folders "
            "of fewer frames."
        )
    from .vdb_layout import VdbTransform

    placed = []
    for frame, (low, _), shift in zip(frames, boxes, shifts):
        density = np.zeros(tuple(size_xyz[::-1]), dtype=np.float32)
        x, y, z = (low - union_low).tolist()
        depth, height, width = frame["density"].shape
        density[z : z + depth, y : y + height, x : x + width] = frame["density"]
        corner = tuple((union_low - shift).tolist())  # the union's corner in this frame's own index space
        placed.append({**frame, "density": density, "transform": VdbTransform(frame["transform"].matrix, corner)})
    return placed


def _format_size(voxel_size) -> str:
    values = [float(f"{v:.6g}") for v in voxel_size]
    return f"{values[0]:g}" if values[0] == values[1] == values[2] else "x".join(f"{v:g}" for v in values)


def _turned(frame: dict) -> dict:
    """A ``.vdb`` frame read with ``turn=False``, turned to its up axis (``vdb.upright``); others as they are.

    Its velocity (``"vdb_velocity"``, the grids as read) is sampled at the voxels of the density's box
    (``vdb.VdbVelocity.at``: world displacement per frame), turned with them, and its world components
    become index steps of the turned transform (``vdb.world_to_index``), so they follow the turn:
    ``(x, y, z)`` of the array as rendered, in voxels per frame, the units of ``mistyle.warp``."""
    if frame.get("transform") is None:
        return frame
    from .vdb_frames import world_to_index
    from .vdb_layout import upright

    density, transform = upright(frame["density"], frame["transform"], frame["up"])
    turned = {**frame, "density": density, "transform": transform}
    read = turned.pop("vdb_velocity", None)
    if read is not None:
        world = read.at(frame["transform"], frame["density"].shape)
        turned["velocity"] = world_to_index(upright(world, frame["transform"], frame["up"])[0], transform)
        turned["velocity_source"] = read.source
    return turned


def _read_density_file(
    path: Path, grid: str | None = None, up: str | None = None, turn: bool = True, motion: dict | None = None
) -> dict:
    """One frame: ``{"density", "velocity"}``, and for ``.vdb`` files ``"transform"`` and ``"up"``.

    ``turn``: turn a ``.vdb`` grid to its up axis here (``vdb.upright``); False leaves it in the file's
    index order (``"up"`` says where to turn it), for ``load_density_frames`` to line frames up first.
    ``motion``: ``{"velocity_grid", "fps"}`` to read a ``.vdb`` file's velocity too (``vdb.read_vdb_frame``);
    until the frame is turned it is the grids as read (``"vdb_velocity"``), then ``"velocity"``.
    """
    check_link(path, "Density", "point --density at a density file")
    if not path.exists():
        raise ValueError(f"Density {path} does not exist.")
    if path.is_dir():
        raise ValueError(
            f"Density {path} is a folder; a folder of frames is a sequence: load it with "
            "mistyle.files.load_density_frames, or give it to mistyle-render --density."
        )
    if not path.is_file():
        raise ValueError(f"Density {path} is not a file.")
    suffix = path.suffix.lower()
    if suffix not in DENSITY_SUFFIXES:
        raise ValueError(
            f"Unsupported density file {path}: use a Mitsuba .vol, an OpenVDB .vdb, a numpy .npy "
            "(Z, Y, X) grid or an .npz with a 'density' array."
        )
    if suffix == ".vdb":
        from .vdb_frames import read_vdb_frame
        from .vdb_layout import recorded_up_axis

        # Both name the file and its grids in their errors.
        read = read_vdb_frame(path, grid, **motion) if motion is not None else read_vdb_frame(path, grid, "")
        up = recorded_up_axis(read.density.file_metadata) if up is None else up
        frame = {
            "density": validate_density(read.density.array, name=os.fspath(path)),
            "velocity": None,
            "vdb_velocity": read.velocity,
            "transform": read.density.transform,
            "up": up,
        }
        return _turned(frame) if turn else frame
    if suffix == ".vol":
        array, velocity = read_vol(path), None  # read_vol names the file in its own errors
    else:
        try:
            array, velocity = _read_npy(path) if suffix == ".npy" else _read_npz(path)
        except (OSError, EOFError, ValueError) as error:
            reason = "not a numpy file of numbers" if "pickle" in str(error) else str(error)
            raise ValueError(f"{path} cannot be read as a density ({reason}).") from None
    density = validate_density(array, name=os.fspath(path))
    if velocity is not None:
        velocity = np.asarray(velocity, np.float32)
        if velocity.shape != density.shape + (3,):
            raise ValueError(
                f"{path}: velocity {velocity.shape} does not match the density grid {density.shape} (+ 3)."
            )
    return {"density": density, "velocity": velocity}


def _npy_header(stream, held: int, limit: int, what: str = "its .npy header") -> tuple[tuple, bool, np.dtype]:
    """The ``(shape, fortran_order, dtype)`` of the ``.npy`` data in ``stream``, of ``held`` bytes, read from
    its header alone; ``ValueError`` when the header is damaged, declares more bytes than the stream holds
    (a truncated file, or a lying header: numpy allocates what it declares before reading), or more than
    ``limit`` values (``conventions.MAX_GRID_VOXELS``)."""
    import tokenize

    from numpy.lib import format as npy

    start = stream.tell()
    try:
        version = npy.read_magic(stream)
        if version == (1, 0):
            shape, fortran, dtype = npy.read_array_header_1_0(stream)
        elif version == (2, 0):
            shape, fortran, dtype = npy.read_array_header_2_0(stream)
        else:  # 3.0 exists for structured arrays' non-latin-1 field names, never for a grid of numbers
            raise ValueError(f"format version {version[0]}.{version[1]} holds no grid of numbers")
    except (ValueError, SyntaxError, TypeError, tokenize.TokenError) as error:  # what numpy's parser raises
        text = error.args[0] if error.args and isinstance(error.args[0], str) else str(error)
        reason = " ".join(text.split()) or type(error).__name__
        raise ValueError(f"{what} is damaged ({reason}); save the array again with np.save") from None
    if dtype.hasobject:
        raise ValueError("it holds Python objects, which would need pickle")
    count = math.prod(shape)
    declared, left = count * dtype.itemsize, held - (stream.tell() - start)
    if declared > left:
        raise ValueError(
            f"{what} declares a {'x'.join(map(str, shape))} array of {dtype} ({declared} bytes), but only "
            f"{left} bytes follow it; the file is truncated or its header is wrong: save the array again"
        )
    if count > limit:
        raise ValueError(
            f"it holds a {'x'.join(map(str, shape))} array ({count} values); mistyle reads grids of up to "
            f"{MAX_GRID_VOXELS} voxels (conventions.MAX_GRID_VOXELS, {MAX_GRID_VOXELS * 4 >> 30} GiB as float32): "
            "crop or downsample it"
        )
    return shape, fortran, dtype


def _read_npy(path: Path) -> tuple[np.ndarray, None]:
    with open(path, "rb") as handle:
        shape, fortran, dtype = _npy_header(handle, os.fstat(handle.fileno()).st_size, MAX_GRID_VOXELS)
        data = np.fromfile(handle, dtype=dtype, count=math.prod(shape))
    return data.reshape(shape, order="F" if fortran else "C"), None


# The largest ratio of deflate's output to its input (RFC 1951: 258 bytes from each 2-bit code, ~1032:1).
_DEFLATE_RATIO = 1032


def _read_npz(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """The ``density`` array and the ``velocity`` array (or None) of an ``.npz``, each member's declared
    sizes checked (``_npy_header``) before its data is read."""
    import zipfile
    import zlib

    size = path.stat().st_size
    try:
        archive = zipfile.ZipFile(path)
    except zipfile.BadZipFile as error:
        raise ValueError(
            f"it is not a complete .npz archive ({error}; a truncated file?): save it again with np.savez"
        ) from None
    arrays = {}
    with archive:
        names = archive.namelist()
        for key, limit in (("density", MAX_GRID_VOXELS), ("velocity", 3 * MAX_GRID_VOXELS)):
            member = f"{key}.npy"
            if member not in names:
                continue
            info = archive.getinfo(member)
            stored = info.compress_type == zipfile.ZIP_STORED and info.file_size == info.compress_size
            deflated = info.compress_type == zipfile.ZIP_DEFLATED and info.file_size <= (
                _DEFLATE_RATIO * info.compress_size + 1024
            )
            if info.compress_size > size or not (stored or deflated):
                raise ValueError(
                    f"its member {member} declares {info.file_size} bytes from {info.compress_size} stored in a "
                    f"{size}-byte file; the archive is damaged: save it again with np.savez"
                )
            try:
                with archive.open(member) as stream:
                    _npy_header(stream, info.file_size, limit, f"the .npy header of its member {member}")
                with archive.open(member) as stream:  # numpy reads its checked header again, then the data
                    arrays[key] = np.lib.format.read_array(stream, allow_pickle=False)
            except (zipfile.BadZipFile, zlib.error, EOFError) as error:
                raise ValueError(f"its member {member} is damaged ({error}): save it again with np.savez") from None
    if "density" not in arrays:
        held = ", ".join(name.removesuffix(".npy") for name in names) or "nothing"
        raise ValueError(f"it has no 'density' array (it holds {held})")
    return arrays["density"], arrays.get("velocity")


def write_npz(path, **arrays) -> Path:
    """A compressed numpy ``.npz`` of named arrays, written atomically."""
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as handle:
            np.savez_compressed(handle, **arrays)
    return Path(path)


def write_npy(path, array: np.ndarray) -> Path:
    """Write a numpy ``.npy`` file atomically."""
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as handle:
            np.save(handle, np.asarray(array), allow_pickle=False)
    return Path(path)
