"""Files: atomic writes, linear EXR and sRGB PNG images.

Every file mistyle writes goes through ``atomic_output``: data lands in a temporary file in the
target directory and is renamed into place only once complete, so a crash or a full disk never
leaves a half-written file that a later run would take for a finished one.
"""

from __future__ import annotations

import contextlib
import os
import struct
import tempfile
import zlib
from pathlib import Path

import numpy as np


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
        raise ValueError(f"Cannot write to the output directory {directory} ({error.strerror or error}); "
                         "choose another --out.") from None
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
            exr.write(str(tmp))
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


def write_png(path, image, srgb: bool = True) -> Path:
    """Write an ``(H, W, 3)`` image with values in [0, 1] as an 8-bit PNG (sRGB-encoded if ``srgb``)."""
    rgb = _as_rgb_image(image)
    encoded = linear_to_srgb(rgb) if srgb else np.clip(rgb, 0.0, 1.0)
    pixels = np.round(encoded * 255.0).astype(np.uint8)
    height, width, _ = pixels.shape
    rows = b"".join(b"\x00" + pixels[row].tobytes() for row in range(height))

    def chunk(kind: bytes, payload: bytes) -> bytes:
        return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))

    png = (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
        + (chunk(b"sRGB", b"\x00") if srgb else b"")
        + chunk(b"IDAT", zlib.compress(rows, 6))
        + chunk(b"IEND", b"")
    )
    return atomic_write_bytes(path, png)
