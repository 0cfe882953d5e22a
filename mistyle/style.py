"""A style, resolved once where it enters (the command line, the API, the preview): its pictures, loaded
and checked, their weights and names, and the one picture it is measured and fitted against.

``Style.of`` takes what users give (a path, an image array, a mix ``[(style, weight)]``, or a ``Style``)
and every stage after it takes the ``Style``: nothing loads a style's files twice, and a mix is a
mosaic (``style_target``) in exactly one place.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from .files import load_style


def style_parts(style) -> list[tuple[object, float]]:
    """``style`` as ``[(image or path, weight)]``: one image or path, or a list of ``(style, weight)``."""
    if isinstance(style, (list, tuple)) and not all(isinstance(p, tuple) and len(p) == 2 for p in style or [None]):
        raise ValueError(
            f"A style is an image (array or path) or a mix [(style, weight), ...]; got a list of {len(style)} "
            "item(s) that are not (style, weight) pairs."
        )
    if isinstance(style, (list, tuple)):
        weights = [float(w) for _, w in style]
        if not all(np.isfinite(w) and w >= 0 for w in weights) or sum(weights) <= 0:
            raise ValueError(f"Style mix weights must be >= 0 with a positive sum, got {weights}.")
        return [(image, float(w)) for image, w in style]
    return [(style, 1.0)]


def style_target(images: list[np.ndarray], weights, height: int = 256) -> np.ndarray:
    """The picture a style's look is measured and refined against: the image itself, or for a mix a
    mosaic ``(height, W, 3)`` of its images side by side, each given a width in proportion to its
    weight (scaled to ``height``, tiled across its strip), so every style's colours and patterns
    count as much as its weight."""
    from PIL import Image

    if len(images) == 1:
        return images[0]
    weights = np.asarray(weights, dtype=np.float64) / np.sum(weights)
    strips = []
    for image, weight in zip(images, weights):
        width = round(height * len(images) * weight)
        if width < 1:
            continue
        scaled = (
            np.asarray(
                Image.fromarray((image * 255 + 0.5).astype(np.uint8)).resize(
                    (max(1, round(image.shape[1] * height / image.shape[0])), height), Image.LANCZOS
                ),
                dtype=np.float32,
            )
            / 255
        )
        repeats = -(-width // scaled.shape[1])
        strips.append(np.tile(scaled, (1, repeats, 1))[:, :width])
    return np.concatenate(strips, axis=1)


@dataclass(frozen=True, eq=False)
class Style:
    """A style's ``images`` (display RGB ``(H, W, 3)`` float32 in [0, 1]), their mix ``weights`` (as given,
    with a positive sum) and ``names`` (what a look and a report call them)."""

    images: tuple
    weights: tuple
    names: tuple

    @classmethod
    def of(cls, style, notes: list | None = None, names: list[str] | None = None) -> Style:
        """``style`` (an image array or path, a mix ``[(style, weight)]``, or a ``Style``, returned as it
        is) with its pictures loaded (``io.load_style``, whose conversions go to ``notes``); ``names``
        default to the files' names ("an image" for an array)."""
        if isinstance(style, Style):
            return style
        parts = style_parts(style)
        images = tuple(load_style(image, notes) for image, _ in parts)
        if names is None:
            names = [Path(image).name if isinstance(image, (str, os.PathLike)) else "an image" for image, _ in parts]
        if len(names) != len(images):
            raise ValueError(f"A style of {len(images)} picture(s) needs as many names, got {len(names)}.")
        return cls(images, tuple(weight for _, weight in parts), tuple(names))

    @property
    def parts(self) -> list[tuple[np.ndarray, float]]:
        """``[(image, weight)]``."""
        return list(zip(self.images, self.weights))

    @property
    def is_mix(self) -> bool:
        return len(self.images) > 1

    @cached_property
    def target(self) -> np.ndarray:
        """The picture the style is measured and fitted against (``style_target``)."""
        return style_target(list(self.images), list(self.weights))

    def describe(self) -> str:
        """The name, or for a mix each name with its share (``0.70 x a.png + 0.30 x b.png``)."""
        if not self.is_mix:
            return self.names[0]
        total = sum(self.weights)
        return " + ".join(f"{weight / total:.2f} x {name}" for name, weight in zip(self.names, self.weights))
