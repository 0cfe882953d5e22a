"""Style pictures, decoded in one place (``load_style``): any image Pillow reads, OpenEXR, or an array."""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from .images import read_exr
from .paths import check_link

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
        from ..tone import display

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
        height, width = values.shape[:2]
        values = _reduced(values, name, notes)
        if min(values.shape[:2]) < MIN_STYLE_SIZE:
            raise ValueError(
                f"{name} is {width}x{height} pixels: brought to {MAX_STYLE_SIDE} pixels on its longer side, as "
                f"every style is, it would be {values.shape[1]}x{values.shape[0]}, under {MIN_STYLE_SIZE} pixels "
                f"on its shorter side. Crop it to a picture at most {MAX_STYLE_SIDE // MIN_STYLE_SIZE} times as "
                "long as it is wide."
            )
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
