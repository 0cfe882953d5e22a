"""Files: every read and write of mistyle's images, volumes, videos and style pictures.

Every file mistyle writes goes through ``atomic_output``: data lands in a temporary file in the
target directory and is renamed into place only once complete, so a crash or a full disk never
leaves a half-written file that a later run would take for a finished one.

Formats: linear OpenEXR and 8-bit PNG images (Pillow), Mitsuba ``.vol`` grids, numpy ``.npy``,
H.264 MP4 (the ffmpeg that ``imageio-ffmpeg`` ships) and GIF (Pillow). Style pictures are decoded
in one place, ``load_style``.
"""

from __future__ import annotations

import contextlib
import errno
import io
import math
import os
import struct
import tempfile
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .conventions import MAX_GRID_VOXELS
from .volume import validate_density


@contextlib.contextmanager
def atomic_output(path):
    """Yield a temporary path next to ``path``; rename it onto ``path`` if the block succeeds."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix, dir=path.parent)
    except OSError as error:
        raise OSError(f"Cannot write {path}: {error.strerror}. Choose a writable output directory.") from error
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600 files; give the usual permissions
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except OSError as error:
        # numpy's short writes raise "N requested and M written" with no errno: a full disk all the same.
        if error.errno == errno.ENOSPC or "requested and" in str(error):
            where = next(p for p in path.absolute().parents if not p.name.startswith("."))  # not a staging folder
            full = OSError(
                f"The disk under {where} is full; nothing was written. Free space there or choose another --out."
            )
            full.errno = errno.ENOSPC
            raise full from None
        raise
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


def check_writable_dir(directory) -> Path:
    """Create ``directory`` if needed and prove a file can be made in it; ``ValueError`` naming the fix."""
    directory = Path(directory)
    try:
        directory.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=directory):
            pass
    except OSError as error:
        raise ValueError(
            f"Cannot write to the output directory {directory} ({error.strerror or error}); choose another --out."
        ) from None
    return directory


def atomic_write_bytes(path, data: bytes) -> Path:
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
    return Path(path)


def _as_rgb_image(image) -> np.ndarray:
    array = np.asarray(image, dtype=np.float32)
    if array.ndim != 3 or array.shape[-1] != 3:
        raise ValueError(f"Images are (H, W, 3) arrays, got shape {array.shape}.")
    return np.ascontiguousarray(array)


def write_exr(path, image) -> Path:
    """Write a linear ``(H, W, 3)`` float image as a float32 OpenEXR file."""
    import OpenEXR

    rgb = _as_rgb_image(image)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with atomic_output(path) as tmp:
        with OpenEXR.File(header, {"RGB": rgb}) as exr:
            try:
                exr.write(str(tmp))
            except RuntimeError as error:  # OpenEXR reports I/O failures as RuntimeError
                raise OSError(errno.ENOSPC if "No space left" in str(error) else None, str(error)) from None
    return Path(path)


def read_exr(path) -> np.ndarray:
    """Read an RGB OpenEXR file as a float32 ``(H, W, 3)`` array.

    Raises:
        ValueError: naming the file, for a truncated or damaged file (``check_exr_layout``) or one
            without R, G and B channels.
    """
    import OpenEXR

    check_exr_layout(path)
    try:
        with OpenEXR.File(str(path)) as exr:
            channels = exr.channels()
            if "RGB" in channels:
                return np.asarray(channels["RGB"].pixels, dtype=np.float32)
            return np.stack([np.asarray(channels[c].pixels, dtype=np.float32) for c in "RGB"], axis=-1)
    except KeyError as error:
        raise ValueError(f"{path} is not an RGB OpenEXR image (it has no {error.args[0]} channel).") from None
    except (RuntimeError, ValueError, OSError) as error:  # OpenEXR's kinds for damaged files
        raise ValueError(f"{path} is not a readable RGB OpenEXR image ({_one_line(error)}).") from None


def _one_line(error: BaseException) -> str:
    text = error.args[0] if error.args and isinstance(error.args[0], str) else str(error)
    return " ".join(text.split()) or type(error).__name__


# Scanlines per chunk of each OpenEXR compression (the header's "compression" byte).
_EXR_LINES_PER_CHUNK = {0: 1, 1: 1, 2: 1, 3: 16, 4: 32, 5: 16, 6: 32, 7: 32, 8: 32, 9: 256}


def check_exr_layout(path) -> None:
    """``ValueError`` naming ``path`` unless it starts as an OpenEXR file and, for a single-part scanline
    image (what mistyle and most tools write), every chunk its offset table lists lies inside the file.

    OpenEXR reads a truncated file's chunk table with a page of messages on stderr and then a bare "file has 0
    parts"; this reads the header and the table (a few hundred bytes) first. Tiled, multi-part and deep
    files, and compressions this table does not list, are left to OpenEXR."""
    path = Path(path)
    size = path.stat().st_size
    fix = "it is truncated or damaged (an interrupted copy or render?); write or export it again"
    with open(path, "rb") as handle:
        head = handle.read(8)
        if len(head) < 8 or head[:4] != b"\x76\x2f\x31\x01":
            raise ValueError(f"{path} is not an OpenEXR file (it does not start with OpenEXR's magic number).")
        if int.from_bytes(head[4:8], "little") & 0x1A00:  # tiled, deep or multi-part
            return
        header = handle.read(1 << 20)  # a megabyte holds the attributes of all but files with large previews
        attributes, position = {}, 0
        while position < len(header) and header[position] != 0:  # attributes: name, type, int32 size, value
            name_end = header.find(b"\x00", position)
            kind_end = header.find(b"\x00", name_end + 1) if name_end >= 0 else -1
            if kind_end < 0 or kind_end + 5 > len(header):
                break
            length = int.from_bytes(header[kind_end + 1 : kind_end + 5], "little", signed=True)
            if length < 0 or kind_end + 5 + length > len(header):
                break
            attributes[header[position:name_end]] = header[kind_end + 5 : kind_end + 5 + length]
            position = kind_end + 5 + length
        if position >= len(header) or header[position] != 0:  # no empty name ended the header in what was read
            if len(header) < size - 8:
                return  # it goes on past the megabyte read: OpenEXR reads it
            raise ValueError(f"{path} ends inside its OpenEXR header at byte {size}; {fix}.")
        position += 1
        compression, window = attributes.get(b"compression"), attributes.get(b"dataWindow")
        if compression is None or window is None or len(window) != 16 or compression[0] not in _EXR_LINES_PER_CHUNK:
            return
        y_min, y_max = (int.from_bytes(window[i : i + 4], "little", signed=True) for i in (4, 12))
        chunks = -(-(y_max - y_min + 1) // _EXR_LINES_PER_CHUNK[compression[0]])
        table = 8 + position
        if chunks < 1 or table + 8 * chunks > size:
            raise ValueError(f"{path} ends inside its table of {max(chunks, 0)} pixel chunks at byte {size}; {fix}.")
        handle.seek(table)
        offsets = np.frombuffer(handle.read(8 * chunks), dtype="<u8")
        for number, offset in enumerate(offsets.tolist()):
            leader = b""
            if table + 8 * chunks <= offset <= size - 8:
                handle.seek(offset)
                leader = handle.read(8)
            packed = int.from_bytes(leader[4:], "little", signed=True) if len(leader) == 8 else -1
            if packed < 0 or offset + 8 + packed > size:
                raise ValueError(
                    f"{path} holds {size} bytes, but its pixel chunk {number + 1} of {chunks} "
                    f"{'starts' if packed < 0 else 'ends'} beyond them; {fix}."
                )


def load_envmap(path) -> np.ndarray:
    """An environment map (``--light envmap:<file.exr>``) as float32 ``(H, W, 3)`` linear radiance.

    Raises:
        ValueError: one line naming the file for a missing file, a symbolic link loop or a broken link,
            a truncated or damaged EXR (Mitsuba would fail mid-scene with a bare "read 0 out of 1
            bytes"), or pixels that are NaN, infinite or negative (each would turn the whole render
            into NaN or a wrong light), with their count.
    """
    path = Path(path)
    what = "The environment map"
    check_link(path, what, "point envmap: at an OpenEXR file")
    if not path.is_file():
        raise ValueError(f"{what} {path} does not exist.")
    if path.suffix.lower() != ".exr":
        raise ValueError(f"{what} {path} is not an OpenEXR (.exr) file; save it as linear OpenEXR.")
    try:
        pixels = read_exr(path)
    except ValueError as error:
        raise ValueError(f"{what} {error}") from None
    checks = (("NaN", np.isnan(pixels)), ("infinite", np.isinf(pixels)), ("negative", pixels < 0))
    bad = [f"{int(mask.any(axis=-1).sum())} {kind}" for kind, mask in checks if mask.any()]
    if bad:
        raise ValueError(
            f"{what} {path} holds {' and '.join(bad)} pixels (of {pixels.shape[1]}x{pixels.shape[0]}); an "
            "environment's radiance must be finite and >= 0: repair them (e.g. np.nan_to_num) and save it again."
        )
    return pixels


def linear_to_srgb(image: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve on linear values, clipped to [0, 1]."""
    x = np.clip(np.asarray(image, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def read_png(path) -> np.ndarray:
    """An 8-bit PNG as ``(H, W, 3)`` uint8 (what ``write_png`` wrote)."""
    from PIL import Image

    with Image.open(path) as image:
        return np.asarray(image.convert("RGB"), dtype=np.uint8).copy()


def write_png(path, image, srgb: bool = True) -> Path:
    """Write an ``(H, W, 3)`` image with values in [0, 1] as an 8-bit PNG (sRGB-encoded if ``srgb``)."""
    from PIL import Image

    rgb = _as_rgb_image(image)
    encoded = linear_to_srgb(rgb) if srgb else np.clip(rgb, 0.0, 1.0)
    pixels = np.round(encoded * 255.0).astype(np.uint8)
    with atomic_output(path) as tmp:
        Image.fromarray(pixels, mode="RGB").save(tmp, format="PNG")
    return Path(path)


def write_npy(path, array: np.ndarray) -> Path:
    """Write a numpy ``.npy`` file atomically."""
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as handle:
            np.save(handle, np.asarray(array), allow_pickle=False)
    return Path(path)


def write_mp4(path, frames: list[np.ndarray], fps: int) -> Path:
    """H.264 MP4 of ``(H, W, 3)`` uint8 frames with the ffmpeg that ``imageio-ffmpeg`` ships."""
    import imageio_ffmpeg

    height, width = frames[0].shape[:2]
    with atomic_output(path) as tmp:
        writer = imageio_ffmpeg.write_frames(
            str(tmp),
            (width, height),
            fps=fps,
            codec="libx264",
            pix_fmt_out="yuv420p",
            macro_block_size=2,
            quality=8,
            output_params=["-f", "mp4"],
        )
        writer.send(None)
        for frame in frames:
            writer.send(np.ascontiguousarray(frame))
        writer.close()
    return Path(path)


def write_gif(path, frames: list[np.ndarray], fps: int) -> Path:
    """An endlessly looping GIF of ``(H, W, 3)`` uint8 frames."""
    from PIL import Image

    with atomic_output(path) as tmp:
        images = [Image.fromarray(frame) for frame in frames]
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0)
    return Path(path)


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
        if len(raw) < _VOL_HEADER.size or raw[:3] != b"VOL":
            raise ValueError(f"{path} is not a Mitsuba .vol file (missing the 'VOL' header).")
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


def density_frame_files(path) -> list[Path]:
    """The frame files of a density: the file itself, or a folder's density files sorted by name."""
    path = Path(path)
    if not path.is_dir():
        return [path]
    candidates = sorted(p for p in path.iterdir() if p.suffix.lower() in DENSITY_SUFFIXES)
    for candidate in candidates:  # a frame left out of a sequence would go unnoticed in the render
        check_link(candidate, "The frame", "restore the frame or remove the link; a sequence renders every frame")
    files = [p for p in candidates if p.is_file()]
    if not files:
        raise ValueError(f"The folder {path} holds no {', '.join(DENSITY_SUFFIXES)} density frames.")
    return files


def load_density_frames(
    path,
    grid: str | None = None,
    up: str | None = None,
    *,
    velocity_grid: str | None = None,
    fps: float | None = None,
    notes: list | None = None,
) -> DensityFrames:
    """Density frames from a file or a folder of frame files (sorted by name).

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
    from .vdb import VdbTransform

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
    from .vdb import upright, world_to_index

    density, transform = upright(frame["density"], frame["transform"], frame["up"])
    turned = {**frame, "density": density, "transform": transform}
    read = turned.pop("vdb_velocity", None)
    if read is not None:
        world = read.at(frame["transform"], frame["density"].shape)
        turned["velocity"] = world_to_index(upright(world, frame["transform"], frame["up"])[0], transform)
        turned["velocity_source"] = read.source
    return turned


def check_link(path: Path, what: str, fix: str) -> None:
    """``ValueError`` naming ``what`` when ``path`` is a symbolic link that leads nowhere: a loop, or a
    link to a file that is gone (``path.exists()`` would only say False, and ``Path.resolve`` raises
    RuntimeError on a loop, so code that resolves an input first should call this before)."""
    try:
        os.stat(path)
    except OSError as error:
        if error.errno == errno.ELOOP:
            raise ValueError(f"{what} {path} is a symbolic link loop (it leads back to itself); {fix}.") from None
        if os.path.islink(path):
            raise ValueError(
                f"{what} {path} is a broken symbolic link (to {os.readlink(path)}, which does not exist); {fix}."
            ) from None


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
            "mistyle.io.load_density_frames, or give it to mistyle-render --density."
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
        from .vdb import read_vdb_frame, recorded_up_axis

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


# ----------------------------------------------------------------------------- style pictures
MIN_STYLE_SIZE = 8
MAX_STYLE_SIDE = 256
"""Styles are reduced to this many pixels on their longer side when decoded, before any metric or objective
sees them: the size of the benchmark's styles, twice what the network and the refinement read (128)."""


def load_style(style, notes: list | None = None) -> np.ndarray:
    """A style picture as float32 ``(H, W, 3)`` display-encoded RGB in [0, 1], from a path or an array.

    Files: anything Pillow reads, converted to sRGB (through the embedded ICC profile when there is
    one; palette, CMYK, greyscale, 16-bit and alpha images included), and OpenEXR (linear radiance,
    shown with the display curve of the renders, ``mistyle.display``). Arrays: ``(H, W)`` or
    ``(H, W, 1|3|4)``, ``uint8``, ``uint16`` or float in [0, 1]. Alpha is composited over black, the
    renders' background. Each conversion is described in ``notes``.

    Raises:
        ValueError: a missing file, a folder, an unreadable or oversized image, an image smaller
            than 8x8, or an array of the wrong shape, type or range.
    """
    notes = [] if notes is None else notes
    if isinstance(style, (str, os.PathLike)):
        return _style_file(Path(style), notes)
    return _style_array(np.asarray(style), "The style array", notes)


def _style_file(path: Path, notes: list) -> np.ndarray:
    from PIL import Image, UnidentifiedImageError

    check_link(path, "Style image", "point --style at an image file")
    if path.is_dir():
        raise ValueError(f"Style {path} is a folder; give one image file.")
    if not path.is_file():
        raise ValueError(f"Style image {path} does not exist.")
    if path.suffix.lower() == ".exr":
        from .tone import display

        notes.append(f"{path}: linear EXR shown with the renders' display curve")
        try:
            return _style_array(display(read_exr(path)), str(path), notes)
        except Exception as error:  # OpenEXR raises several kinds for damaged files
            raise ValueError(f"{path} is not a readable RGB OpenEXR image ({error}).") from None
    try:
        with Image.open(path) as image:
            if image.format == "JPEG" and max(image.size) > 2 * MAX_STYLE_SIDE:
                # Decode at 1/2, 1/4 or 1/8 scale, never below the working size: a fraction of the memory.
                scale = MAX_STYLE_SIDE / max(image.size)
                full = image.size
                image.draft("RGB", (round(image.size[0] * scale), round(image.size[1] * scale)))
                notes.append(f"{path}: {full[0]}x{full[1]} JPEG decoded at {image.size[0]}x{image.size[1]}")
            image.load()
            rgb = _pil_to_array(image, str(path), notes)
    except Image.DecompressionBombError:
        raise ValueError(
            f"{path} has more than {2 * Image.MAX_IMAGE_PIXELS} pixels, Pillow's safety limit; "
            "downscale it (a style needs no more than a few megapixels)."
        ) from None
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as error:
        raise ValueError(f"{path} is not a readable image ({error}); use a PNG, JPEG or EXR file.") from None
    return _style_array(rgb, str(path), notes)


def _pil_to_array(image, name: str, notes: list) -> np.ndarray:
    """A Pillow image as an ``(H, W, C)`` array (C in 1-4) that ``_style_array`` understands."""
    from PIL import ImageCms

    frames = getattr(image, "n_frames", 1)
    if frames > 1:
        notes.append(f"{name}: an animated image of {frames} frames; its first frame is the style")
    icc = image.info.get("icc_profile")
    if image.mode == "P" or image.mode == "PA":
        has_alpha = image.mode == "PA" or "transparency" in image.info
        image = image.convert("RGBA" if has_alpha else "RGB")
        notes.append(f"{name}: palette image expanded to RGB")
    elif image.mode == "1":
        image = image.convert("L")
    elif image.mode in ("RGBa", "La"):  # premultiplied alpha
        image = image.convert("RGBA" if image.mode == "RGBa" else "LA")
    if icc and image.mode in ("RGB", "RGBA", "CMYK", "L", "LA"):
        try:
            source = ImageCms.ImageCmsProfile(io.BytesIO(icc))
            description = ImageCms.getProfileDescription(source).strip()
            alpha = image.getchannel("A") if "A" in image.getbands() else None
            colour = image.convert({"RGBA": "RGB", "LA": "L"}.get(image.mode, image.mode))
            converted = ImageCms.profileToProfile(colour, source, ImageCms.createProfile("sRGB"), outputMode="RGB")
            if alpha is not None:
                converted.putalpha(alpha)
            if "srgb" not in description.lower():
                notes.append(f"{name}: converted from its colour profile ({description}) to sRGB")
            image = converted
        except (ImageCms.PyCMSError, OSError, ValueError):
            notes.append(f"{name}: its embedded colour profile is unreadable; colours read as sRGB")
    if image.mode in ("CMYK", "YCbCr", "LAB", "HSV"):
        notes.append(f"{name}: {image.mode} image converted to RGB")
        image = image.convert("RGB")
    if image.mode.startswith("I;16") or image.mode == "I":
        array = np.asarray(image).astype(np.float32) / 65535.0
        notes.append(f"{name}: 16-bit image scaled to [0, 1]")
        return array
    if image.mode == "F":
        return np.asarray(image, dtype=np.float32)
    if image.mode not in ("L", "LA", "RGB", "RGBA"):
        image = image.convert("RGBA" if "A" in image.getbands() else "RGB")
    return np.asarray(image)


def _style_array(array: np.ndarray, name: str, notes: list) -> np.ndarray:
    if array.ndim == 2:
        array = array[..., None]
    if array.ndim != 3 or array.shape[-1] not in (1, 2, 3, 4):
        raise ValueError(f"{name} must be (H, W, 3) (or 1, 2 or 4 channels), got shape {array.shape}.")
    if array.dtype == np.uint8:
        values = array.astype(np.float32) / 255.0
    elif array.dtype == np.uint16:
        values = array.astype(np.float32) / 65535.0
        notes.append(f"{name}: 16-bit image scaled to [0, 1]")
    elif array.dtype == np.bool_:
        values = array.astype(np.float32)
    elif np.issubdtype(array.dtype, np.floating):
        values = array.astype(np.float32)
        if not np.all(np.isfinite(values)):
            bad = int(np.count_nonzero(~np.isfinite(values)))
            raise ValueError(f"{name} holds {bad} NaN or infinite value(s); a style needs finite values in [0, 1].")
        if values.min() < 0 or values.max() > 1:
            raise ValueError(
                f"{name} must hold finite values in [0, 1] (display-encoded sRGB), "
                f"got [{np.nanmin(values):.4g}, {np.nanmax(values):.4g}]."
            )
    else:
        raise ValueError(f"{name} has the pixel type {array.dtype}; use uint8, uint16 or float in [0, 1].")
    channels = values.shape[-1]
    if channels in (2, 4) and not values[..., -1].any():
        raise ValueError(f"{name} is fully transparent (alpha 0 everywhere): it has no colours to give a medium.")
    if channels in (2, 4):  # alpha: composite over black, the renders' background
        values = values[..., :-1] * values[..., -1:]
        notes.append(f"{name}: alpha composited over black (the renders' background)")
    if values.shape[-1] == 1:
        values = np.repeat(values, 3, axis=-1)
        notes.append(f"{name}: greyscale replicated to RGB")
    if min(values.shape[:2]) < MIN_STYLE_SIZE:
        raise ValueError(
            f"{name} is {values.shape[1]}x{values.shape[0]} pixels; a style image needs at least "
            f"{MIN_STYLE_SIZE}x{MIN_STYLE_SIZE}."
        )
    if max(values.shape[:2]) > MAX_STYLE_SIDE:
        values = _reduced(values, name, notes)
    return np.ascontiguousarray(np.clip(values, 0.0, 1.0), dtype=np.float32)


def _reduced(values: np.ndarray, name: str, notes: list) -> np.ndarray:
    """``values (H, W, 3)`` resampled (Lanczos, per channel in float) to ``MAX_STYLE_SIDE`` on its longer side."""
    from PIL import Image

    height, width = values.shape[:2]
    scale = MAX_STYLE_SIDE / max(height, width)
    size = (max(1, round(width * scale)), max(1, round(height * scale)))
    channels = [np.asarray(Image.fromarray(values[..., c], mode="F").resize(size, Image.LANCZOS)) for c in range(3)]
    notes.append(
        f"{name}: {width}x{height} reduced to {size[0]}x{size[1]} (styles are used at up to "
        f"{MAX_STYLE_SIDE} pixels a side)"
    )
    return np.stack(channels, axis=-1)
