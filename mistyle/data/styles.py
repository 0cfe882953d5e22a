"""Style images: reading users' images and folders, and the offline default style set.

Images are float32 ``(H, W, 3)`` RGB in [0, 1] (sRGB-encoded, as photographs are stored).

The offline default set needs no download. It combines
  * the colour photographs scikit-image ships inside its wheel, all public domain or CC0
    (astronaut, chelsea, coffee, hubble_deep_field, immunohistochemistry, retina, rocket), cut into
    several crops each;
  * its CC0 textures brick, grass and gravel (from CC0Textures), colourised with random palettes;
  * procedural material textures made with FastNoise Lite: marble, jade, fire, wood, cells, clouds,
    lava, each with random palettes and seeds (about 2 ms per 128^2 image);
  * the public-domain and CC0 paintings, prints and textures shipped in ``PAINTINGS_DIR`` (source and
    licence of each in its ``SOURCES.toml``): the whole picture and random crops of a half to a
    quarter of its side, so brush strokes show at more than one scale.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..conventions import STYLE_SUFFIXES
from ..files import load_style
from .heldout import check_training_styles

PHOTOS = {
    "astronaut": "astronaut.png",
    "chelsea": "chelsea.png",
    "coffee": "coffee.png",
    "hubble_deep_field": "hubble_deep_field.jpg",
    "immunohistochemistry": "ihc.png",
    "retina": "retina.jpg",
    "rocket": "rocket.jpg",
}
TEXTURES = {"brick": "brick.png", "grass": "grass.png", "gravel": "gravel.png"}
MATERIALS = ("marble", "jade", "fire", "wood", "cells", "clouds", "lava")
PAINTINGS_DIR = Path(__file__).resolve().parent / "paintings"
"""Public-domain paintings shipped for training (source and licence per file in ``SOURCES.toml``), taken
from other repositories than the fidelity benchmark's held-out styles (``tests/test_heldout.py``)."""


def random_crop(image: np.ndarray, size: int, rng: np.random.Generator) -> np.ndarray:
    """A random ``size x size`` crop; images smaller than ``size`` are first scaled up (bilinear)."""
    height, width = image.shape[:2]
    if min(height, width) < size:
        import torch
        import torch.nn.functional as F

        scale = size / min(height, width)
        target = (max(size, round(height * scale)), max(size, round(width * scale)))
        tensor = torch.from_numpy(image).permute(2, 0, 1)[None]
        image = F.interpolate(tensor, size=target, mode="bilinear", align_corners=False)[0].permute(1, 2, 0).numpy()
        height, width = target
    top, left = int(rng.integers(0, height - size + 1)), int(rng.integers(0, width - size + 1))
    return np.ascontiguousarray(image[top : top + size, left : left + size])


@dataclass
class ImageFolder:
    """Every style picture under ``root`` (``conventions.STYLE_SUFFIXES``; DTD's ``images/<class>/*.jpg`` included).

    A folder holding any of the fidelity benchmark's held-out styles is refused (``data.heldout``).

    Unreadable files are skipped when first read and counted in ``skipped``. ``split()`` assigns
    each file to train or held-out by a hash of its relative path, so the split is stable when
    files are added.
    """

    root: Path
    paths: list[Path] = field(default_factory=list)
    skipped: list[Path] = field(default_factory=list)

    def __post_init__(self):
        self.root = Path(self.root)
        if not self.root.is_dir():
            raise ValueError(f"Style folder {self.root} does not exist or is not a directory.")
        self.paths = sorted(p for p in self.root.rglob("*") if p.suffix.lower() in STYLE_SUFFIXES and p.is_file())
        if not self.paths:
            raise ValueError(f"No images ({', '.join(STYLE_SUFFIXES)}) under {self.root}.")
        check_training_styles(self.paths)  # the fidelity benchmark's styles must stay unseen

    def split(self, holdout_fraction: float = 0.1) -> tuple[list[Path], list[Path]]:
        def held_out(path: Path) -> bool:
            digest = hashlib.sha1(str(path.relative_to(self.root)).encode()).digest()
            return int.from_bytes(digest[:8], "little") / 2**64 < holdout_fraction

        held = [p for p in self.paths if held_out(p)]
        return [p for p in self.paths if not held_out(p)], held

    def load_all(self, paths: list[Path] | None = None) -> list[np.ndarray]:
        """Read images, skipping (and recording) the unreadable ones."""
        images = []
        for path in self.paths if paths is None else paths:
            try:
                images.append(load_style(path))
            except ValueError:
                self.skipped.append(path)
        if not images:
            raise ValueError(f"None of the {len(self.paths)} images under {self.root} could be read.")
        return images


# ----------------------------------------------------------------------- offline default set
def skimage_data_dir() -> Path:
    import skimage

    return Path(os.path.dirname(skimage.__file__)) / "data"


def palette(rng: np.random.Generator, stops: int = 3) -> np.ndarray:
    """Random colour ramp: ``stops`` RGB colours in [0, 1], shape ``(stops, 3)``, dark to light."""
    hue = rng.uniform(0, 1)
    colours = []
    for index in range(stops):
        h = (hue + rng.normal(0, 0.08)) % 1.0
        value = 0.15 + 0.8 * index / max(stops - 1, 1)
        saturation = rng.uniform(0.3, 0.9)
        colours.append(_hsv_to_rgb(h, saturation, value))
    return np.array(colours, dtype=np.float32)


def _hsv_to_rgb(h, s, v):
    import colorsys

    return colorsys.hsv_to_rgb(h, s, v)


def apply_palette(gray: np.ndarray, colours: np.ndarray) -> np.ndarray:
    """Map values in [0, 1] through a piecewise-linear colour ramp; ``(H, W) -> (H, W, 3)``."""
    positions = np.linspace(0.0, 1.0, len(colours))
    return np.stack([np.interp(np.clip(gray, 0, 1), positions, colours[:, c]) for c in range(3)], axis=-1).astype(
        np.float32
    )


def material_texture(kind: str, size: int = 128, seed: int = 0) -> np.ndarray:
    """A procedural material texture ``(size, size, 3)`` in [0, 1]."""
    from pyfastnoiselite.pyfastnoiselite import (
        CellularReturnType,
        FastNoiseLite,
        FractalType,
        NoiseType,
    )

    if kind not in MATERIALS:
        raise ValueError(f"Unknown material {kind!r}; choose one of {MATERIALS}.")
    rng = np.random.default_rng([seed, MATERIALS.index(kind)])
    noise = FastNoiseLite(int(rng.integers(0, 2**31 - 1)))
    noise.noise_type = NoiseType.NoiseType_OpenSimplex2
    noise.fractal_type = FractalType.FractalType_FBm
    noise.fractal_octaves = 5
    noise.frequency = float(rng.uniform(0.008, 0.02))
    ys, xs = np.meshgrid(np.arange(size, dtype=np.float32), np.arange(size, dtype=np.float32), indexing="ij")
    coords = np.stack([xs.ravel(), ys.ravel()])
    fbm = noise.gen_from_coords(coords).reshape(size, size) * 0.5 + 0.5
    if kind == "marble":
        gray = 0.5 + 0.5 * np.sin(xs * rng.uniform(0.05, 0.15) + 12.0 * fbm)
        colours = np.array([[0.35, 0.33, 0.32], [0.85, 0.83, 0.8], [0.97, 0.96, 0.94]]) * rng.uniform(0.9, 1.05, (1, 3))
    elif kind == "jade":
        gray = np.clip(1.4 * fbm - 0.2, 0, 1)
        colours = np.array([[0.05, 0.25, 0.12], [0.25, 0.6, 0.35], [0.7, 0.9, 0.7]])
    elif kind == "fire":
        gray = np.clip(fbm * (1.2 - ys / size) * 1.6, 0, 1)
        colours = np.array([[0.05, 0.0, 0.0], [0.8, 0.15, 0.0], [1.0, 0.6, 0.05], [1.0, 0.95, 0.6]])
    elif kind == "wood":
        rings = np.sqrt((xs - size * rng.uniform(-1, 2)) ** 2 + (ys * 0.2) ** 2) * rng.uniform(0.04, 0.08) + 2.5 * fbm
        gray = rings - np.floor(rings)
        colours = np.array([[0.3, 0.16, 0.06], [0.55, 0.33, 0.15], [0.75, 0.52, 0.3]])
    elif kind == "cells":
        noise.noise_type = NoiseType.NoiseType_Cellular
        noise.fractal_type = FractalType.FractalType_None
        noise.cellular_return_type = CellularReturnType.CellularReturnType_Distance2Sub
        noise.frequency = float(rng.uniform(0.03, 0.08))
        gray = np.clip(noise.gen_from_coords(coords).reshape(size, size) * 0.5 + 0.5, 0, 1)
        colours = palette(rng, 3)
    elif kind == "clouds":
        gray = np.clip((fbm - 0.3) * 2.0, 0, 1)
        colours = np.array([[0.25, 0.45, 0.8], [0.7, 0.8, 0.95], [1.0, 1.0, 1.0]])
    else:  # lava
        gray = np.clip(1.0 - np.abs(2.0 * fbm - 1.0) * 3.0, 0, 1)
        colours = np.array([[0.08, 0.05, 0.05], [0.6, 0.1, 0.02], [1.0, 0.7, 0.2]])
    return apply_palette(gray, np.asarray(colours, dtype=np.float32))


def painting_crops(image: np.ndarray, size: int, count: int, rng: np.random.Generator) -> list[np.ndarray]:
    """The whole (square-cropped) picture, then ``count - 1`` random square crops of 1/4 to 1/2 of its
    side, each resized to ``size x size``."""
    from ..model.features import square_style

    side = min(image.shape[:2])
    crops = [image]
    for _ in range(count - 1):
        crop = max(16, int(side * rng.uniform(0.25, 0.5)))
        top, left = int(rng.integers(0, image.shape[0] - crop + 1)), int(rng.integers(0, image.shape[1] - crop + 1))
        crops.append(image[top : top + crop, left : left + crop])
    return [square_style(crop, size).permute(1, 2, 0).numpy() for crop in crops]


def offline_style_set(
    size: int = 128,
    crops_per_photo: int = 6,
    palettes_per_texture: int = 4,
    materials_each: int = 6,
    crops_per_painting: int = 3,
    seed: int = 0,
) -> list[tuple[str, np.ndarray]]:
    """The offline default style set: ``(name, image (size, size, 3))`` pairs; names are ``source/stem_index``."""
    rng = np.random.default_rng(seed)
    styles = []
    data = skimage_data_dir()
    for name, filename in PHOTOS.items():
        photo = load_style(data / filename)
        for index in range(crops_per_photo):
            styles.append((f"photo/{name}_{index}", random_crop(photo, size, rng)))
    for name, filename in TEXTURES.items():
        gray = load_style(data / filename)[..., 0]
        for index in range(palettes_per_texture):
            crop = random_crop(gray[..., None].repeat(3, -1), size, rng)[..., 0]
            styles.append((f"texture/{name}_{index}", apply_palette(crop, palette(rng))))
    for kind in MATERIALS:
        for index in range(materials_each):
            styles.append((f"material/{kind}_{index}", material_texture(kind, size, seed=seed * 1000 + index)))
    for path in sorted(PAINTINGS_DIR.glob("*.jpg")) if crops_per_painting else ():
        for index, crop in enumerate(painting_crops(load_style(path), size, crops_per_painting, rng)):
            styles.append((f"painting/{path.stem}_{index}", crop))
    return styles


def style_set_diversity(styles: list[tuple[str, np.ndarray]]) -> dict:
    """Summary numbers: count per source, and the spread of mean colours and contrasts."""
    means = np.array([image.reshape(-1, 3).mean(0) for _, image in styles])
    stds = np.array([image.reshape(-1, 3).std(0).mean() for _, image in styles])
    pairwise = np.linalg.norm(means[:, None] - means[None], axis=-1)
    sources: dict[str, int] = {}
    for name, _ in styles:
        sources[name.split("/")[0]] = sources.get(name.split("/")[0], 0) + 1
    return {
        "count": len(styles),
        "by_source": sources,
        "mean_pairwise_colour_distance": float(pairwise[np.triu_indices(len(styles), 1)].mean()),
        "hue_coverage": float(_hue_coverage(means)),
        "contrast_range": [float(stds.min()), float(stds.max())],
    }


def _hue_coverage(means: np.ndarray, bins: int = 12) -> float:
    import colorsys

    hues = [colorsys.rgb_to_hsv(*m)[0] for m in means if max(m) - min(m) > 0.05]
    return len(set(int(h * bins) % bins for h in hues)) / bins
