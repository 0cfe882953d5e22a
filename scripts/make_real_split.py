"""Rebuild the benchmark's ``real`` split (``mistyle/benchmark/real/*.npz``) from the recorded sources.

    python scripts/make_real_split.py --mirror /work/.mirror          # fetched bare git snapshots
    python scripts/make_real_split.py --sources FOLDER                # plain copies of the source files
    python scripts/make_real_split.py --sources FOLDER --check        # rebuild in memory, compare, write nothing

``mistyle/benchmark/real/SOURCES.toml`` names each volume's source: a public repository, the commit, the
path in it, the file's SHA-256, its licence and author, and how to read it (format, grid, up axis). This
script never downloads anything. Give it the source files one of two ways:

* ``--sources FOLDER``: each file at ``FOLDER/<owner>+<name>/<path>`` (the repository's own path, under a
  folder named after the repository with ``/`` written ``+``), or directly at ``FOLDER/<file name>``;
* ``--mirror FOLDER``: bare git directories at ``FOLDER/<owner>+<name>/repo`` (or ``.../<owner>+<name>``),
  read with ``git show <commit>:<path>`` -- the layout the project's ``fetch`` tool leaves.

Every source is checked against its recorded SHA-256 before it is used. The conversion, the same for
every volume:

1. read the density (``mistyle.files``: ``.vdb`` by grid name, turned so the recorded world up axis is the
   array's Y; Mitsuba ``.vol`` as stored, then ``turn``: ``x180`` rotates it 180 degrees about x, for a
   file whose world is -y up), negatives set to 0;
2. crop to the bounding box of the voxels above ``1e-3`` x the 99.9th percentile of the non-zero voxels;
3. if the longest side exceeds 126, average down (area resampling, ``adaptive_avg_pool3d``) so it is 126,
   keeping the aspect (the factor is recorded);
4. divide by the 99.9th percentile of the non-zero voxels (recorded, in the source's units), clip to
   [0, 1], set values below 1e-4 to 0;
5. pad one empty voxel on every side (so the longest side is at most 128 and nothing is cut at the
   box's faces) and store float16 ``density`` in a compressed ``.npz``.

``--update-record`` writes what step 1-5 measured (shapes, crop, factor, normaliser, stored digest,
occupancy) back into SOURCES.toml; without it the script checks them and fails on a difference.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import tomllib

ROOT = Path(__file__).resolve().parent.parent
REAL_DIR = ROOT / "mistyle" / "benchmark" / "real"
SOURCES = REAL_DIR / "SOURCES.toml"

MAX_INTERIOR = 126  # the longest side after resampling; one empty voxel each side makes it <= 128
PAD = 1
PERCENTILE = 99.9
CROP_FRACTION = 1e-3  # of the source's 99.9th percentile: what counts as inside the active bounding box
FLOOR = 1e-4  # normalised values below this are stored as 0

HEADER = """\
# The benchmark's `real` split: clouds and smoke that other people simulated or captured, from public
# repositories, each converted by scripts/make_real_split.py (crop to the active box, area-resampled to
# at most 126 voxels on the longest side, divided by the 99.9th percentile of its non-zero voxels and
# clipped to [0, 1], one empty voxel of margin, float16). The fields under [<name>.stored] are written by
# `python scripts/make_real_split.py --update-record`; the rest is the record of where each came from.
#
# kind: dense when at least 5% of its box holds at least half the normalised maximum (`occupancy`
# under [<name>.stored]: a thick cloud, an opaque core or source block); thin otherwise (smoke: wisps
# far below the maximum). licence: the SPDX identifier of the licence the file is published under in that repository
# (licence_note says where it comes from, and where the data's origin is older than the repository).
"""

KEY_ORDER = (
    "file",
    "kind",
    "description",
    "repo",
    "commit",
    "path",
    "source_sha256",
    "licence",
    "licence_note",
    "author",
    "origin",
    "url",
    "format",
    "grid",
    "up",
    "turn",
)
STORED_ORDER = (
    "source_shape_zyx",
    "crop_zyx",
    "cropped_shape_zyx",
    "resample_factor",
    "normaliser",
    "clipped_fraction",
    "shape_zyx",
    "occupancy",
    "mean_active",
    "density_sha256",
    "bytes",
)


# ----------------------------------------------------------------------------- the record
def read_record(path: Path = SOURCES) -> dict[str, dict]:
    return tomllib.loads(path.read_text())


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(float(f"{value:.6g}"))
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"')
        return f'"{escaped}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(item) for item in value) + "]"
    raise TypeError(f"cannot write {value!r} to TOML")


def write_record(record: dict[str, dict], path: Path = SOURCES) -> None:
    lines = [HEADER]
    for name, entry in record.items():
        lines.append(f"[{name}]")
        keys = [key for key in KEY_ORDER if key in entry] + sorted(set(entry) - set(KEY_ORDER) - {"stored"})
        lines += [f"{key} = {_toml_value(entry[key])}" for key in keys]
        stored = entry.get("stored")
        if stored:
            lines.append(f"\n[{name}.stored]")
            keys = [key for key in STORED_ORDER if key in stored] + sorted(set(stored) - set(STORED_ORDER))
            lines += [f"{key} = {_toml_value(stored[key])}" for key in keys]
        lines.append("")
    path.write_text("\n".join(lines))


# ----------------------------------------------------------------------------- finding the sources
def repo_folder(repo: str) -> str:
    return repo.replace("/", "+")


def source_bytes(entry: dict, sources: Path | None, mirror: Path | None) -> bytes:
    """The recorded source file's bytes, from a folder of copies or a fetched bare git directory."""
    repo, path, commit = entry["repo"], entry["path"], entry["commit"]
    tried = []
    if sources is not None:
        for candidate in (sources / repo_folder(repo) / path, sources / Path(path).name):
            tried.append(str(candidate))
            if candidate.is_file():
                return candidate.read_bytes()
    if mirror is not None:
        for git_dir in (mirror / repo_folder(repo) / "repo", mirror / repo_folder(repo)):
            tried.append(f"{git_dir} ({commit[:12]}:{path})")
            if (git_dir / "HEAD").exists() or (git_dir / "objects").is_dir():
                result = subprocess.run(
                    ["git", "--git-dir", str(git_dir), "show", f"{commit}:{path}"], capture_output=True
                )
                if result.returncode == 0:
                    return result.stdout
    raise SystemExit(f"error: the source of {entry['file']} ({repo} {path}) is not in: " + "; ".join(tried))


# ----------------------------------------------------------------------------- the conversion
def read_source(data: bytes, entry: dict) -> np.ndarray:
    """The source density ``(Z, Y, X)`` float32, turned so that its world up is the array's Y."""
    from mistyle.files import load_density_frames, read_vol

    suffix = {"vdb": ".vdb", "vol": ".vol"}[entry["format"]]
    with tempfile.TemporaryDirectory() as folder:
        file = Path(folder) / f"source{suffix}"
        file.write_bytes(data)
        if entry["format"] == "vdb":
            array = load_density_frames(file, grid=entry.get("grid", "density"), up=entry.get("up", "y")).densities[0]
        else:
            array = read_vol(file)
            if array.ndim == 4:
                array = array[..., 0]
    turn = entry.get("turn", "none")
    if turn == "x180":  # a proper rotation: y -> -y, z -> -z
        array = array[::-1, ::-1, :]
    elif turn != "none":
        raise SystemExit(f"error: {entry['file']}: unknown turn {turn!r} (none or x180)")
    array = np.nan_to_num(np.asarray(array, dtype=np.float32), nan=0.0, posinf=0.0, neginf=0.0)
    return np.ascontiguousarray(np.maximum(array, 0.0))


def area_resample(array: np.ndarray, shape: tuple[int, int, int]) -> np.ndarray:
    import torch

    if tuple(array.shape) == tuple(shape):
        return array
    tensor = torch.from_numpy(np.ascontiguousarray(array, dtype=np.float32))[None, None]
    return torch.nn.functional.adaptive_avg_pool3d(tensor, shape)[0, 0].numpy()


def convert(source: np.ndarray) -> tuple[np.ndarray, dict]:
    """The stored float16 grid of an oriented source density, and what each step measured."""
    active = source[source > 0]
    if active.size == 0:
        raise SystemExit("error: the source density is empty")
    level = float(np.percentile(active, PERCENTILE)) * CROP_FRACTION
    inside = np.argwhere(source > level)
    low, high = inside.min(axis=0), inside.max(axis=0) + 1
    cropped = source[low[0] : high[0], low[1] : high[1], low[2] : high[2]]
    longest = max(cropped.shape)
    factor = min(1.0, MAX_INTERIOR / longest)
    shape = tuple(max(1, round(n * factor)) for n in cropped.shape)
    resampled = area_resample(cropped, shape)
    normaliser = float(np.percentile(resampled[resampled > 0], PERCENTILE))
    scaled = resampled / normaliser
    clipped = float((scaled > 1.0).mean())
    scaled = np.clip(scaled, 0.0, 1.0)
    scaled[scaled < FLOOR] = 0.0
    stored = np.pad(scaled, PAD).astype(np.float16)
    values = stored.astype(np.float32)
    return stored, {
        "source_shape_zyx": [int(n) for n in source.shape],
        "crop_zyx": [[int(a), int(b)] for a, b in zip(low, high)],
        "cropped_shape_zyx": [int(n) for n in cropped.shape],
        "resample_factor": float(factor),
        "normaliser": normaliser,
        "clipped_fraction": clipped,
        "shape_zyx": [int(n) for n in stored.shape],
        "occupancy": float((values >= 0.5).sum() / math.prod(scaled.shape)),  # of the box inside the margin
        "mean_active": float(values[values > 0].mean()),
        "density_sha256": hashlib.sha256(np.ascontiguousarray(stored).tobytes()).hexdigest(),
    }


def npz_bytes(stored: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, density=stored)
    return buffer.getvalue()


def differences(recorded: dict, measured: dict) -> list[str]:
    out = []
    for key, value in measured.items():
        old = recorded.get(key)
        if isinstance(value, float):
            same = old is not None and math.isclose(old, value, rel_tol=1e-4, abs_tol=1e-6)
        else:
            same = old == value
        if not same:
            out.append(f"{key}: recorded {old!r}, measured {value!r}")
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sources", type=Path, default=None, help="folder of source files (see above)")
    p.add_argument("--mirror", type=Path, default=None, help="folder of fetched bare git directories")
    p.add_argument("--out", type=Path, default=REAL_DIR, help=f"where the .npz files go (default: {REAL_DIR})")
    p.add_argument("--only", default=None, help="comma-separated volume names (default: all)")
    p.add_argument("--check", action="store_true", help="rebuild in memory and compare; write nothing")
    p.add_argument("--update-record", action="store_true", help="write the measured values into SOURCES.toml")
    args = p.parse_args(argv)
    if args.sources is None and args.mirror is None:
        p.error("give --sources FOLDER or --mirror FOLDER (this script downloads nothing)")
    sys.path.insert(0, str(ROOT))
    record = read_record()
    names = args.only.split(",") if args.only else list(record)
    unknown = sorted(set(names) - set(record))
    if unknown:
        p.error(f"unknown volume(s) {', '.join(unknown)}; SOURCES.toml has {', '.join(record)}")
    problems = []
    for name in names:
        entry = record[name]
        data = source_bytes(entry, args.sources, args.mirror)
        digest = hashlib.sha256(data).hexdigest()
        if digest != entry["source_sha256"]:
            raise SystemExit(
                f"error: {name}: the source file's SHA-256 is {digest}, the record says {entry['source_sha256']}"
            )
        stored, measured = convert(read_source(data, entry))
        blob = npz_bytes(stored)
        measured["bytes"] = len(blob)
        recorded = entry.get("stored", {})
        found = differences(recorded, {k: v for k, v in measured.items() if k != "bytes"})
        print(
            f"{name:22s} {entry['kind']:5s} source {'x'.join(map(str, measured['source_shape_zyx'])):>13s} -> "
            f"{'x'.join(map(str, measured['shape_zyx'])):>11s} (factor {measured['resample_factor']:.3f}, "
            f"p99.9 {measured['normaliser']:.4g}, occupancy {measured['occupancy']:.3f}, "
            f"mean {measured['mean_active']:.3f}) {len(blob):>9d} bytes"
            + ("" if not found or args.update_record else "  DIFFERS: " + "; ".join(found))
        )
        if found and not args.update_record:
            problems.append(name)
        if args.update_record:
            entry["stored"] = measured
        if not args.check:
            args.out.mkdir(parents=True, exist_ok=True)
            (args.out / entry["file"]).write_bytes(blob)
    if args.update_record:
        write_record(record)
        print(f"wrote {SOURCES}")
    if problems:
        print(f"error: {', '.join(problems)} differ from SOURCES.toml (--update-record to accept)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
