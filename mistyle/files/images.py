"""Images and videos: linear OpenEXR, 8-bit PNG, environment maps, H.264 MP4 (the ffmpeg that
``imageio-ffmpeg`` ships) and GIF (Pillow)."""

from __future__ import annotations

import errno
from pathlib import Path

import numpy as np

from .paths import atomic_output, check_link, one_line


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
    """Read an RGB OpenEXR file as a float32 ``(H, W, 3)`` array; a luminance-only one (its ``Y`` channel,
    as greyscale images are written) as grey.

    Raises:
        ValueError: naming the file, for a truncated or damaged file (``check_exr_layout``) or one
            without R, G and B channels (nor Y).
    """
    import OpenEXR

    check_exr_layout(path)
    try:
        with OpenEXR.File(str(path)) as exr:
            channels = exr.channels()
            if "RGB" in channels:
                return np.asarray(channels["RGB"].pixels, dtype=np.float32)
            if "Y" in channels and "R" not in channels:
                grey = np.asarray(channels["Y"].pixels, dtype=np.float32)
                return np.repeat(grey[..., None], 3, axis=-1)
            return np.stack([np.asarray(channels[c].pixels, dtype=np.float32) for c in "RGB"], axis=-1)
    except KeyError as error:
        raise ValueError(f"{path} is not an RGB OpenEXR image (it has no {error.args[0]} channel).") from None
    except (RuntimeError, ValueError, OSError) as error:  # OpenEXR's kinds for damaged files
        raise ValueError(f"{path} is not a readable RGB OpenEXR image ({one_line(error)}).") from None


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


def _display_pixels(image, srgb: bool) -> np.ndarray:
    """An ``(H, W, 3)`` image with values in [0, 1] as 8-bit pixels (sRGB-encoded if ``srgb``)."""
    rgb = _as_rgb_image(image)
    encoded = linear_to_srgb(rgb) if srgb else np.clip(rgb, 0.0, 1.0)
    return np.round(encoded * 255.0).astype(np.uint8)


def write_png(path, image, srgb: bool = True) -> Path:
    """Write an ``(H, W, 3)`` image with values in [0, 1] as an 8-bit PNG (sRGB-encoded if ``srgb``)."""
    from PIL import Image

    with atomic_output(path) as tmp:
        Image.fromarray(_display_pixels(image, srgb), mode="RGB").save(tmp, format="PNG")
    return Path(path)


def write_jpeg(path, image, srgb: bool = True, quality: int = 88) -> Path:
    """``write_png``'s image as a JPEG: for figures of renders, a quarter of the PNG's size."""
    from PIL import Image

    with atomic_output(path) as tmp:
        Image.fromarray(_display_pixels(image, srgb), mode="RGB").save(tmp, format="JPEG", quality=quality)
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
