"""Smoke training data: plumes -> frames on disk, with velocity and the cached Ls grid.

Layout of an output directory::

    plume0003/frame0061.npz     density (Z,Y,X) float32, velocity (Z,Y,X,3) float16 (x,y,z),
                                ls (Z,Y,X) float16 for density_scale, plus scalar metadata
                                (``load_frame`` returns float32 arrays)
    plume0003/frame0061_crop2.npz   the same for random crops of high-resolution plumes
    manifest.json               (manifest.shard-I-of-N.json for a shard) files, shapes, pairs, seed...

Generation is deterministic per seed (plume ``p`` draws its parameters from ``(seed, p)``), resumable
(complete files are skipped; every file is written to a temporary name and renamed), and
shardable (``--shard i/n`` takes plumes ``p`` with ``p % n == i``).
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..conventions import DEFAULT_DENSITY_SCALE, LS_DIRECTIONS
from ..files import atomic_write_bytes, write_npz
from ..progress import bar, status
from ..version import __version__

GENERATOR_VERSION = f"mistyle-smoke-{__version__}-1"


@dataclass
class SmokeDatasetSpec:
    resolution: int = 64
    plumes: int = 100
    frames: int = 90
    keep_first: int = 61  # first kept frame (1-based, as the paper's 61-90)
    keep_last: int = 90
    crop: int = 0  # > 0: store random crops of this size instead of whole frames
    crops_per_frame: int = 5
    seed: int = 0
    density_scale: float = DEFAULT_DENSITY_SCALE
    directions: int = LS_DIRECTIONS

    def validate(self) -> None:
        if self.resolution < 8:
            raise ValueError(f"--res must be >= 8, got {self.resolution}.")
        if self.plumes < 1 or self.frames < 2:
            raise ValueError("Need at least one plume and two frames.")
        if not 1 <= self.keep_first <= self.keep_last <= self.frames:
            raise ValueError(f"The kept frames {self.keep_first}-{self.keep_last} must lie within 1-{self.frames}.")
        if self.crop and not 4 <= self.crop <= self.resolution:
            raise ValueError(f"--crop must lie in [4, {self.resolution}], got {self.crop}.")


def plume_rng(seed: int, plume: int) -> np.random.Generator:
    return np.random.default_rng([seed, plume])


def frame_path(out: Path, plume: int, frame: int, crop: int | None = None) -> Path:
    suffix = "" if crop is None else f"_crop{crop}"
    return out / f"plume{plume:04d}" / f"frame{frame:04d}{suffix}.npz"


def generate_smoke(spec: SmokeDatasetSpec, out: Path, shard: tuple[int, int] = (0, 1), log=status) -> Path:
    """Write the plumes of ``shard`` and their manifest; returns the manifest path."""
    import torch

    from ..backend import active_variant
    from ..integrators.inscatter import inscattered_radiance
    from .smoke import PlumeConfig, simulate

    spec.validate()
    index, count = shard
    if not 0 <= index < count:
        raise ValueError(f"--shard must be i/n with 0 <= i < n, got {index}/{count}.")
    torch.set_flush_denormal(True)  # denormals make solver timings swing wildly
    active_variant()
    out.mkdir(parents=True, exist_ok=True)
    records, pairs = [], []
    started, simulated = time.perf_counter(), 0
    plumes = range(index, spec.plumes, count)
    progress_bar = bar(len(plumes), "simulating plumes", unit="plume")
    for plume in plumes:
        rng = plume_rng(spec.seed, plume)
        config = PlumeConfig.random((spec.resolution,) * 3, rng)
        crop_rng = np.random.default_rng([spec.seed, plume, 1])
        kept = list(range(spec.keep_first, spec.keep_last + 1))
        crop_ids = list(range(spec.crops_per_frame)) if spec.crop else [None]
        # Crop windows are drawn per plume, so consecutive frames (the training pairs) share them.
        windows = [_crop_window(spec, crop_rng) for _ in crop_ids]
        paths = {(f, c): frame_path(out, plume, f, c) for f in kept for c in crop_ids}
        if all(p.is_file() for p in paths.values()):
            log(f"plume {plume}: complete, skipped")
        else:
            for frame0, density, velocity in simulate(config, spec.keep_last, seed=spec.seed * 100_003 + plume):
                simulated += 1
                frame = frame0 + 1
                if frame not in kept:
                    continue
                for crop_id, window in zip(crop_ids, windows):
                    path = paths[(frame, crop_id)]
                    if path.is_file():
                        continue
                    d, v = _cropped(density, window, spec.crop), _cropped(velocity, window, spec.crop)
                    ls = inscattered_radiance(d * np.float32(spec.density_scale), spec.directions)
                    _write_frame(path, d, v, ls, spec, plume, frame)
            log(f"plume {plume}: {len(paths)} files")
        progress_bar.update(1)
        for (frame, crop_id), path in sorted(paths.items(), key=lambda item: (item[0][0], item[0][1] or 0)):
            shape = [spec.crop] * 3 if spec.crop else [spec.resolution] * 3
            records.append(
                {"path": str(path.relative_to(out)), "plume": plume, "frame": frame, "crop": crop_id, "shape": shape}
            )
            if frame + 1 in kept:
                pairs.append([str(path.relative_to(out)), str(paths[(frame + 1, crop_id)].relative_to(out))])
    progress_bar.close()
    manifest = {
        "generator": GENERATOR_VERSION,
        "spec": asdict(spec),
        "shard": [index, count],
        "files": records,
        "pairs": pairs,
        "arrays": {
            "density": "(Z,Y,X) float32",
            "velocity": "(Z,Y,X,3) float16, (x,y,z), voxels/frame",
            "ls": "(Z,Y,X) float16, Ls for unit radiance at spec.density_scale",
        },
        "seconds": time.perf_counter() - started,
        "simulated_frames": simulated,
    }
    name = "manifest.json" if count == 1 else f"manifest.shard-{index}-of-{count}.json"
    return atomic_write_bytes(out / name, (json.dumps(manifest, indent=1) + "\n").encode())


def _crop_window(spec: SmokeDatasetSpec, rng: np.random.Generator):
    if not spec.crop:
        return None
    return tuple(int(rng.integers(0, spec.resolution - spec.crop + 1)) for _ in range(3))


def _cropped(array: np.ndarray, window, size: int) -> np.ndarray:
    """The ``size^3`` block at ``window = (z, y, x)``; the whole array when ``window`` is None."""
    if window is None:
        return array
    z, y, x = window
    return np.ascontiguousarray(array[z : z + size, y : y + size, x : x + size])


def _write_frame(path: Path, density, velocity, ls, spec: SmokeDatasetSpec, plume: int, frame: int) -> None:
    # float16 halves the disk for the two fields that tolerate it (1e-3 relative).
    write_npz(
        path,
        density=density.astype(np.float32),
        velocity=velocity.astype(np.float16),
        ls=ls.astype(np.float16),
        density_scale=np.float32(spec.density_scale),
        directions=np.int32(spec.directions),
        plume=np.int32(plume),
        frame=np.int32(frame),
    )


def generate_fire(
    resolution: int, frames: int, keep: tuple[int, int], out: Path, seed: int = 0, log=status
) -> list[Path]:
    """One fire sequence: ``frameNNNN.npz`` with the flame ``density`` and ``velocity`` for each kept frame."""
    import torch

    from .smoke import FireConfig, simulate

    if resolution < 8 or not 1 <= keep[0] <= keep[1] <= frames:
        raise ValueError(f"Need --res >= 8 and kept frames within 1-{frames}; got {resolution}, {keep}.")
    torch.set_flush_denormal(True)
    config = FireConfig(resolution=(resolution,) * 3, source_radius=0.1)
    written = []
    with bar(keep[1], "simulating fire", unit="frame") as progress_bar:
        for frame0, flame, velocity in simulate(config, keep[1], seed=seed):
            frame = frame0 + 1
            progress_bar.update(1)
            if frame >= keep[0]:
                path = out / f"frame{frame:04d}.npz"
                if not path.is_file():
                    write_npz(
                        path,
                        density=flame.astype(np.float32),
                        velocity=velocity.astype(np.float16),
                        frame=np.int32(frame),
                    )
                written.append(path)
    log(f"fire: {len(written)} frames in {out}")
    return written


def load_frame(path) -> dict:
    """Read one frame file; raises ``ValueError`` for a damaged or foreign file."""
    try:
        with np.load(path, allow_pickle=False) as data:
            frame = {key: data[key] for key in data.files}
    except (OSError, ValueError, EOFError) as error:
        raise ValueError(
            f"{path} is not a readable mistyle frame file ({error}); delete it and re-run generation."
        ) from error
    missing = {"density", "velocity", "ls"} - frame.keys()
    if missing:
        raise ValueError(f"{path} lacks {sorted(missing)}; it was not written by mistyle.data.")
    for key in ("density", "velocity", "ls"):
        frame[key] = frame[key].astype(np.float32)
    return frame
