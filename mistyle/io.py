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
import os
import struct
import tempfile
from pathlib import Path
from typing import NamedTuple

import numpy as np

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


@contextlib.contextmanager
def output_lock(directory, wait: bool = False):
    """Hold the lock file beside ``directory`` for the block; yield ``(directory, parent)``. A second run
    into the same output is refused while it is held (``wait``: waits for it instead), and staging
    folders left beside it by a killed run are removed."""
    import fcntl
    import shutil

    directory = Path(directory).absolute()  # "--out ." has no name of its own to stage beside
    if directory.name in ("", ".", ".."):
        directory = directory.resolve()
    parent = directory.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        lock = open(parent / f".{directory.name}.lock", "w")  # noqa: SIM115 - held for the whole block
    except OSError as error:
        raise ValueError(
            f"Cannot write to the output directory {directory} ({error.strerror or error}); choose another --out."
        ) from None
    try:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX if wait else fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise ValueError(
                f"Another mistyle run is writing to {directory}; wait for it to finish or choose another --out."
            ) from None
        if directory.exists() and not directory.is_dir():
            raise ValueError(f"The output path {directory} is a file; choose a folder for --out.")
        # Holding the lock, no other run writes this output: staging folders beside it are a killed run's.
        stale = [p for kind in ("partial", "replaced") for p in parent.glob(f".{directory.name}.{kind}-*")]
        for folder in stale:
            shutil.rmtree(folder, ignore_errors=True)
        if stale:
            from .progress import status

            status(f"note: removed {len(stale)} unfinished staging folder(s) of an earlier run beside {directory}")
        yield directory, parent
    finally:
        with contextlib.suppress(OSError):
            os.unlink(parent / f".{directory.name}.lock")
        lock.close()


def _staging_folder(directory: Path, parent: Path) -> Path:
    staging = Path(tempfile.mkdtemp(prefix=f".{directory.name}.partial-", dir=parent))
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(staging, 0o777 & ~umask)  # mkdtemp makes 0700 folders; the output gets the usual mode
    return staging


@contextlib.contextmanager
def staged_directory(directory):
    """Yield an empty staging folder; when the block succeeds, it becomes ``directory`` whole.

    The staging folder is a hidden sibling of ``directory``, so the final rename stays on one file
    system. An existing ``directory`` is replaced only once the new one is complete; a failure or an
    interrupt removes the staging folder and leaves ``directory`` as it was. A lock file beside it
    refuses a second run into the same ``directory`` while one is in progress, so a finished folder
    always comes from one run.
    """
    import shutil

    with output_lock(directory) as (directory, parent):
        staging = _staging_folder(directory, parent)
        try:
            yield staging
            if directory.exists():
                retired = Path(tempfile.mkdtemp(prefix=f".{directory.name}.replaced-", dir=parent))
                os.replace(directory, retired / directory.name)
                os.replace(staging, directory)
                shutil.rmtree(retired, ignore_errors=True)
            else:
                os.replace(staging, directory)
        finally:
            shutil.rmtree(staging, ignore_errors=True)


@contextlib.contextmanager
def chunk_staging(directory):
    """Yield an empty staging folder beside ``directory`` for one chunk of a sequence, removed after the
    block. It takes no lock: chunks render side by side (on a farm, at once) and each merges its
    files into ``directory`` under ``output_lock(directory, wait=True)`` (``merge_files``)."""
    import shutil

    directory = Path(directory).absolute()
    if directory.name in ("", ".", ".."):
        directory = directory.resolve()
    try:
        directory.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{directory.name}.chunk-", dir=directory.parent))
    except OSError as error:
        raise ValueError(
            f"Cannot write to the output directory {directory} ({error.strerror or error}); choose another --out."
        ) from None
    try:
        yield staging
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def merge_files(staging: Path, directory: Path) -> list[str]:
    """Move every file of ``staging`` (``chunk_staging``) into ``directory``, each replacing its namesake
    atomically and keeping the others; returns the names moved. Hold ``output_lock(directory)``."""
    Path(directory).mkdir(parents=True, exist_ok=True)
    moved = []
    for path in sorted(Path(staging).iterdir()):
        if path.is_file():
            os.replace(path, Path(directory) / path.name)
            moved.append(path.name)
    return moved


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
    """Read an RGB OpenEXR file as a float32 ``(H, W, 3)`` array."""
    import OpenEXR

    with OpenEXR.File(str(path)) as exr:
        channels = exr.channels()
        if "RGB" in channels:
            return np.asarray(channels["RGB"].pixels, dtype=np.float32)
        return np.stack([np.asarray(channels[c].pixels, dtype=np.float32) for c in "RGB"], axis=-1)


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
    """Read a float32 Mitsuba ``.vol`` file; returns ``(Z, Y, X)`` for one channel, else ``(Z, Y, X, C)``."""
    raw = Path(path).read_bytes()
    if len(raw) < _VOL_HEADER.size or raw[:3] != b"VOL":
        raise ValueError(f"{path} is not a Mitsuba .vol file (missing the 'VOL' header).")
    magic, version, encoding, x, y, z, c, *_bbox = _VOL_HEADER.unpack_from(raw)
    if version != 3 or encoding != 1:
        raise ValueError(
            f"{path}: only .vol version 3 with float32 data is supported (got version {version}, encoding {encoding})."
        )
    if min(x, y, z, c) < 1:
        raise ValueError(
            f"{path}: the header gives the grid size {x}x{y}x{z} with {c} channels; every size must be >= 1."
        )
    count = x * y * z * c
    if len(raw) - _VOL_HEADER.size != 4 * count:
        raise ValueError(
            f"{path}: header says {x}x{y}x{z}x{c} floats but the file holds {(len(raw) - _VOL_HEADER.size) // 4}."
        )
    data = np.frombuffer(raw, dtype="<f4", offset=_VOL_HEADER.size, count=count).reshape(z, y, x, c)
    data = np.array(data, dtype=np.float32)
    return data[..., 0] if c == 1 else data


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
    files = sorted(p for p in path.iterdir() if p.suffix.lower() in DENSITY_SUFFIXES and p.is_file())
    if not files:
        raise ValueError(f"The folder {path} holds no {', '.join(DENSITY_SUFFIXES)} density frames.")
    return files


def load_density_frames(path, grid: str | None = None, up: str | None = None) -> DensityFrames:
    """Density frames from a file or a folder of frame files (sorted by name).

    ``.npz`` frames of ``python -m mistyle.data`` carry each frame's velocity ``(Z, Y, X, 3)``; the
    velocities are returned only when every frame has one. All frames must share one grid size.

    ``up``: the world up axis of ``.vdb`` frames (``conventions.UP_AXES``; ``z`` for Blender's). Each grid
    is turned so that the index axis closest to it is the array's Y, which mistyle renders as up, and its
    transform follows (``vdb.upright``: every voxel stays where it was). None: what a file mistyle wrote
    says (``mistyle_up_axis``), else ``y``. Other files are in mistyle's own box, whose up is y.
    """
    path = Path(path)
    files = density_frame_files(path)
    frames = [_read_density_file(file, grid, up) for file in files]
    shapes = {frame["density"].shape for frame in frames}
    if len(shapes) > 1:
        raise ValueError(
            f"The frames in {path} have different shapes {sorted(shapes)}; a sequence needs one grid size."
        )
    velocities = [frame.get("velocity") for frame in frames]
    transforms = [frame.get("transform") for frame in frames]
    return DensityFrames(
        [frame["density"] for frame in frames],
        velocities if all(v is not None for v in velocities) else None,
        [file.stem for file in files],
        transforms if all(t is not None for t in transforms) else None,
        frames[0].get("up"),
    )


def _read_density_file(path: Path, grid: str | None = None, up: str | None = None) -> dict:
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
        from .vdb import read_vdb_grid, recorded_up_axis, upright

        read = read_vdb_grid(path, grid)  # names the file and its grids in its errors
        up = recorded_up_axis(read.file_metadata) if up is None else up
        array, transform = upright(read.array, read.transform, up)
        return {
            "density": validate_density(array, name=os.fspath(path)),
            "velocity": None,
            "transform": transform,
            "up": up,
        }
    if suffix == ".vol":
        array, velocity = read_vol(path), None  # read_vol names the file in its own errors
    else:
        try:
            if suffix == ".npy":
                array, velocity = np.load(path, allow_pickle=False), None
            else:
                with np.load(path, allow_pickle=False) as data:
                    arrays = {key: data[key] for key in ("density", "velocity") if key in data.files}
                    held = ", ".join(data.files) or "nothing"
                if "density" not in arrays:
                    raise ValueError(f"it has no 'density' array (it holds {held})")
                array, velocity = arrays["density"], arrays.get("velocity")
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
STYLE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".bmp", ".gif", ".exr")


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

    if path.is_dir():
        raise ValueError(f"Style {path} is a folder; give one image file.")
    if not path.is_file():
        raise ValueError(f"Style image {path} does not exist.")
    if path.suffix.lower() == ".exr":
        from .display import display

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
