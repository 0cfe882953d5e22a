"""The held-out split of the style-fidelity benchmark: styles and densities that training never sees.

This module is the one place the split is recorded. Training draws its styles from scikit-image's
photographs and textures, procedural materials and users' folders, and its densities from the smoke
solver with the dataset seeds of ``configs/`` (0 and up); the benchmark uses

* styles: the images under ``mistyle/data/heldout_styles/`` (paintings, photographs and material
  textures from other sources; each file's source and licence in ``SOURCES.toml`` there), and
* densities: ``HELD_OUT_DENSITIES``, made by ``held_out_density`` from seeds no training set uses
  (smoke at 64^3 and 128^3, and densities from other generators: a pyroclastic cloud and a
  voxelized mesh).

Choosing between checkpoints and recipes uses a validation split drawn the same way and kept apart
from both: the images under ``mistyle/data/validation_styles/`` (paintings by other painters,
photographs and textures, from repositories neither training nor the held-out set took from) and
``VALIDATION_DENSITIES`` (the same generators, other seeds). ``check_training_styles`` refuses a
training style folder holding a held-out or validation image (compared by content, so a renamed copy
is caught too); ``tests/test_heldout.py`` checks the offline set and the configs' seeds.
"""

from __future__ import annotations

import hashlib
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomllib

HELD_OUT_STYLE_DIR = Path(__file__).resolve().parent / "heldout_styles"
"""The held-out styles: package data, so an installed mistyle benchmarks without the repository."""
VALIDATION_STYLE_DIR = Path(__file__).resolve().parent / "validation_styles"
"""The validation styles: the held-out set's kinds of picture from other sources, for model selection."""
HELD_OUT_SEED_BASE = 7000
"""Seeds of held-out densities start here; training datasets use small seeds (``tests/test_heldout.py``)."""


@dataclass(frozen=True)
class HeldOutDensity:
    name: str
    kind: str  # "smoke" | "pyroclastic" | "mesh"
    resolution: int
    seed: int
    frame: int = 0  # smoke: the simulated frame kept (0-based)

    def describe(self) -> str:
        what = {
            "smoke": "smoke from mistyle's solver",
            "pyroclastic": "procedural pyroclastic cloud",
            "mesh": "voxelized noise-displaced mesh",
        }[self.kind]
        return f"{what}, {self.resolution}^3, seed {self.seed}" + (
            f", frame {self.frame}" if self.kind == "smoke" else ""
        )


HELD_OUT_DENSITIES = (
    HeldOutDensity("smoke64", "smoke", 64, HELD_OUT_SEED_BASE + 1, frame=69),
    HeldOutDensity("smoke128", "smoke", 128, HELD_OUT_SEED_BASE + 2, frame=89),
    HeldOutDensity("pyroclastic64", "pyroclastic", 64, HELD_OUT_SEED_BASE + 3),
    HeldOutDensity("rock64", "mesh", 64, HELD_OUT_SEED_BASE + 4),
)


VALIDATION_DENSITIES = (
    HeldOutDensity("val_smoke64", "smoke", 64, HELD_OUT_SEED_BASE + 101, frame=69),
    HeldOutDensity("val_pyroclastic64", "pyroclastic", 64, HELD_OUT_SEED_BASE + 103),
    HeldOutDensity("val_smoke64_b", "smoke", 64, HELD_OUT_SEED_BASE + 105, frame=69),
    HeldOutDensity("val_pyroclastic64_b", "pyroclastic", 64, HELD_OUT_SEED_BASE + 107),
)
"""Densities for choosing between checkpoints (the benchmark's ``validation`` split): the held-out
split's two kinds, two of each, made by the same generators from other seeds, so model selection
never looks at the benchmark's pairs. Two of a kind because networks this close trade places from one
density of a kind to the next (docs/decisions/2026-12-03-validation-split.md)."""


def held_out_density(spec: HeldOutDensity, cache: Path | None = None) -> np.ndarray:
    """The density ``(Z, Y, X)`` float32 of ``spec``; cached as ``<cache>/<name>.npy`` when ``cache`` is given."""
    from ..files import write_npy

    path = None if cache is None else Path(cache) / f"{spec.name}.npy"
    if path is not None and path.exists():
        return np.load(path)
    if spec.kind == "smoke":
        from .smoke import PlumeConfig, simulate

        config = PlumeConfig.random((spec.resolution,) * 3, np.random.default_rng([spec.seed, 0]))
        _, grid, _ = deque(simulate(config, spec.frame + 1, seed=spec.seed), maxlen=1)[0]  # the last frame
    elif spec.kind == "pyroclastic":
        from .procedural import pyroclastic_sphere

        grid = pyroclastic_sphere((spec.resolution,) * 3, radius=0.3, amplitude=0.16, falloff=0.06, seed=spec.seed)
    elif spec.kind == "mesh":
        from .mesh import displaced_icosphere, voxelize

        grid = voxelize(*displaced_icosphere(spec.seed), spec.resolution, supersample=2) * 0.5
    else:
        raise ValueError(f"Unknown held-out density kind {spec.kind!r}.")
    grid = np.ascontiguousarray(grid, dtype=np.float32)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_npy(path, grid)
    return grid


def held_out_styles(root: Path = HELD_OUT_STYLE_DIR) -> dict[str, dict]:
    """``name -> record`` of the held-out styles (``SOURCES.toml``), each with its ``path``; with
    ``root=VALIDATION_STYLE_DIR``, the validation styles (``validation_styles``)."""
    sources = root / "SOURCES.toml"
    if not sources.exists():
        raise ValueError(f"The style list {sources} is missing.")
    records = tomllib.loads(sources.read_text())
    for name, record in records.items():
        record["path"] = root / record["file"]
        if not record["path"].exists():
            raise ValueError(f"Held-out style {name}: {record['path']} is missing.")
    return records


def validation_styles() -> dict[str, dict]:
    """``name -> record`` of the validation styles (``VALIDATION_STYLE_DIR``), as ``held_out_styles``."""
    return held_out_styles(VALIDATION_STYLE_DIR)


def file_digest(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def check_training_styles(paths) -> None:
    """``ValueError`` when any of ``paths`` is a held-out benchmark style or a validation style (by content)."""
    kept = {}
    for root, what in ((VALIDATION_STYLE_DIR, "validation"), (HELD_OUT_STYLE_DIR, "held-out benchmark")):
        if (root / "SOURCES.toml").exists():
            kept.update({file_digest(record["path"]): (name, what) for name, record in held_out_styles(root).items()})
    for path in paths:
        if (digest := file_digest(path)) in kept:
            name, what = kept[digest]
            raise ValueError(
                f"{path} is the {what} style {name!r}; training must never see it. Remove it from the "
                f"training style folder."
            )


def held_out_sequence(first: int, count: int, cache: Path | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Frames ``first .. first + count - 1`` (0-based) of the simulation the held-out ``smoke64`` is frame
    69 of: densities ``(T, Z, Y, X)`` and velocities ``(T, Z, Y, X, 3)`` float32 (each frame's own: frame
    ``t``'s moves it to ``t + 1``); cached as ``<cache>/smoke64_frames<first>-<last>.npz`` when given."""
    from .smoke import PlumeConfig, simulate

    path = None if cache is None else Path(cache) / f"smoke64_frames{first}-{first + count - 1}.npz"
    if path is not None and path.exists():
        data = np.load(path)
        return data["densities"].astype(np.float32), data["velocities"].astype(np.float32)
    spec = next(s for s in HELD_OUT_DENSITIES if s.name == "smoke64")
    config = PlumeConfig.random((spec.resolution,) * 3, np.random.default_rng([spec.seed, 0]))
    frames = [(d, v) for t, d, v in simulate(config, first + count, seed=spec.seed) if t >= first]
    densities = np.stack([d for d, _ in frames]).astype(np.float32)
    velocities = np.stack([v for _, v in frames]).astype(np.float32)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, densities=densities, velocities=velocities)
    return densities, velocities
