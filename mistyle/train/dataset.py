"""Training data: smoke frame pairs (t, t+1, velocity, cached Ls) and style images, split for validation.

* ``SmokePairs`` reads a manifest written by ``python -m mistyle.data smoke``; the last
  ``val_plumes`` plumes are held out, so validation densities come from simulations never trained on.
* ``StyleSet`` holds styles as ``(N, 3, S, S)`` float32 in [0, 1]. For the built-in offline set the
  last variant of every photo, texture and material (crop, palette or seed) is held out, and whole
  paintings (every crop of one picture) by a stable hash of their name; for a folder of images the
  split is the folder's stable hash split (``ImageFolder.split``). ``augment_styles`` rotates hues
  and mirrors a batch, so a few hundred pictures give many palettes.

Both check their inputs when built, so an empty or foreign dataset fails before training starts.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from ..data.generate import SmokeDatasetSpec, generate_smoke, load_frame
from ..data.tiny import TINY_SMOKE
from ..model.features import square_style

# The bundled dataset specs ``data.make`` can generate when the dataset directory is missing.
DATASET_SPECS = {
    "tiny": TINY_SMOKE,
    "cpu": SmokeDatasetSpec(resolution=32, plumes=24, frames=60, keep_first=41, keep_last=60, seed=0, directions=64),
}


PAINTING_VAL_FRACTION = 0.12
"""The share of the offline set's paintings held out (whole pictures) for validation."""

# Three held-out offline styles of different kinds (photo, tinted texture, procedural material) used
# by the comparisons that report "3 unseen styles"; other style sources use evenly spaced picks.
COMPARISON_STYLES = ("photo/coffee_5", "texture/brick_3", "material/lava_5")


@dataclass
class FramePair:
    first: Path
    second: Path
    plume: int


class SmokePairs:
    """Consecutive-frame pairs of a smoke dataset, split by plume into train and validation."""

    def __init__(self, root: str | Path, val_plumes: int = 1, make: str = "", log=print):
        self.root = Path(root)
        manifest_path = self.root / "manifest.json"
        if not manifest_path.is_file() and make:
            log(f"data: {manifest_path} is missing; generating the {make!r} smoke dataset there")
            generate_smoke(DATASET_SPECS[make], self.root, log=log)
        if not manifest_path.is_file():
            raise ValueError(
                f"No smoke dataset at {self.root} (missing manifest.json). Generate one with "
                f"`python -m mistyle.data smoke --res 32 --plumes 24 --frames 60 --keep 41-60 --out {self.root}`, "
                'or set data.make = "cpu" to have training generate it.'
            )
        try:
            manifest = json.loads(manifest_path.read_text())
            self.density_scale = float(manifest["spec"]["density_scale"])
            pairs = manifest["pairs"]
            plume_of = {record["path"]: int(record["plume"]) for record in manifest["files"]}
        except (OSError, ValueError, KeyError, TypeError) as error:
            raise ValueError(f"{manifest_path} is not a mistyle smoke manifest ({error}).") from None
        all_pairs = [FramePair(self.root / a, self.root / b, plume_of[a]) for a, b in pairs]
        if not all_pairs:
            raise ValueError(
                f"The smoke dataset at {self.root} has no frame pairs; generate at least two kept frames per plume."
            )
        listed = dict.fromkeys(path for pair in all_pairs for path in (pair.first, pair.second))
        missing = [path for path in listed if not path.is_file()]
        if missing:
            raise ValueError(
                f"{len(missing)} frame files listed in {manifest_path} are missing, e.g. {missing[0]}; "
                "re-run generation."
            )
        plumes = sorted({p.plume for p in all_pairs})
        if len(plumes) <= val_plumes:
            raise ValueError(
                f"The dataset at {self.root} has {len(plumes)} plumes; "
                f"data.val_plumes={val_plumes} leaves none to train on."
            )
        held_out = set(plumes[-val_plumes:])
        self.train = [p for p in all_pairs if p.plume not in held_out]
        self.val = [p for p in all_pairs if p.plume in held_out]
        first = load_frame(self.train[0].first)
        self.shape = tuple(first["density"].shape)

    def load(self, pair: FramePair) -> dict:
        """``density0/1 (Z,Y,X)``, frame t's ``ls0 (Z,Y,X)`` and ``velocity0 (3,Z,Y,X)`` (x,y,z) as float32."""
        a, b = load_frame(pair.first), load_frame(pair.second)
        for path, frame in ((pair.first, a), (pair.second, b)):
            if frame["density"].shape != self.shape:
                raise ValueError(
                    f"{path} holds a {frame['density'].shape} density; the dataset's frames are {self.shape}. "
                    "Delete it and re-run generation."
                )
        return {
            "density0": a["density"],
            "density1": b["density"],
            "ls0": a["ls"],
            "velocity0": np.ascontiguousarray(np.moveaxis(a["velocity"], -1, 0)),
        }


class StyleSet:
    """Training and held-out style images, resized to ``size`` squares, as ``(N, 3, S, S)`` tensors."""

    def __init__(self, source: str = "offline", size: int = 128):
        self.source = source
        if source == "offline":
            from ..data.styles import offline_style_set

            named = offline_style_set(size=size)
            last = {}
            for name, _ in named:
                stem, _, index = name.rpartition("_")
                last[stem] = max(last.get(stem, -1), int(index))
            is_held = [_held_out_offline(name, last) for name, _ in named]
            train = [(n, im) for (n, im), held in zip(named, is_held) if not held]
            val = [(n, im) for (n, im), held in zip(named, is_held) if held]
        else:
            from ..data.styles import ImageFolder

            folder = ImageFolder(Path(source))
            train_paths, val_paths = folder.split()
            if not train_paths or not val_paths:
                raise ValueError(
                    f"The style folder {source} needs at least two images (one is held out for validation); "
                    f"it has {len(folder.paths)}."
                )
            train = [(str(p.relative_to(folder.root)), im) for p, im in zip(train_paths, folder.load_all(train_paths))]
            val = [(str(p.relative_to(folder.root)), im) for p, im in zip(val_paths, folder.load_all(val_paths))]
        self.train_names, self.train = [n for n, _ in train], _as_batch([im for _, im in train], size)
        self.val_names, self.val = [n for n, _ in val], _as_batch([im for _, im in val], size)

    def comparison_styles(self, count: int = 3) -> list[int]:
        """Indices into ``val`` of ``count`` held-out styles for comparisons (see ``COMPARISON_STYLES``)."""
        chosen = [self.val_names.index(name) for name in COMPARISON_STYLES if name in self.val_names][:count]
        if len(chosen) < count:
            spaced = np.linspace(0, len(self.val_names) - 1, count).round().astype(int).tolist()
            chosen += [i for i in spaced if i not in chosen][: count - len(chosen)]
        return chosen


def _held_out_offline(name: str, last: dict) -> bool:
    stem, _, index = name.rpartition("_")
    if name.startswith("painting/"):  # every crop of a held-out picture, so validation never sees it
        digest = hashlib.sha1(stem.encode()).digest()
        return int.from_bytes(digest[:8], "little") / 2**64 < PAINTING_VAL_FRACTION
    return int(index) == last[stem]


def validation_paintings() -> list[Path]:
    """The paintings the offline set holds out for validation (whole pictures, ``PAINTING_VAL_FRACTION``)."""
    from ..data.styles import PAINTINGS_DIR

    return [path for path in sorted(PAINTINGS_DIR.glob("*.jpg")) if _held_out_offline(f"painting/{path.stem}_0", {})]


def training_paintings() -> list[Path]:
    """The paintings the offline set trains on (whole pictures): the complement of ``validation_paintings``."""
    from ..data.styles import PAINTINGS_DIR

    held_out = set(validation_paintings())
    return [path for path in sorted(PAINTINGS_DIR.glob("*.jpg")) if path not in held_out]


def augment_styles(styles: torch.Tensor, rng: np.random.Generator, hue_probability: float) -> torch.Tensor:
    """Styles ``(B, 3, S, S)`` with, each, probability ``hue_probability`` of a random rotation of its hues
    about the grey axis (luminance kept, values clipped to [0, 1]) and an even chance of a mirror image.
    ``hue_probability = 0`` turns augmentation off (the styles come back as they are, no mirrors)."""
    if hue_probability <= 0:
        return styles
    out = []
    for style in styles:
        if rng.random() < hue_probability:
            style = (
                (hue_rotation(float(rng.uniform(0, 2 * np.pi))).to(style) @ style.flatten(1)).view_as(style).clamp(0, 1)
            )
        if rng.random() < 0.5:
            style = style.flip(-1)
        out.append(style)
    return torch.stack(out)


def hue_rotation(angle: float) -> torch.Tensor:
    """``(3, 3)`` RGB matrix rotating hues by ``angle`` radians about the grey axis (YIQ chroma rotation)."""
    to_yiq = torch.tensor([[0.299, 0.587, 0.114], [0.596, -0.274, -0.322], [0.211, -0.523, 0.312]])
    c, s = np.cos(angle), np.sin(angle)
    rotate = torch.tensor([[1.0, 0, 0], [0, c, -s], [0, s, c]], dtype=torch.float32)
    return torch.linalg.inv(to_yiq) @ rotate @ to_yiq


def _as_batch(images: list[np.ndarray], size: int) -> torch.Tensor:
    return torch.stack([square_style(image, size) for image in images])
