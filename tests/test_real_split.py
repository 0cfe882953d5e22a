"""The benchmark's ``real`` split: densities other people made, each with its source and licence recorded."""

from __future__ import annotations

import fnmatch
import hashlib
import re
from pathlib import Path

import numpy as np
import pytest
import tomllib

from mistyle.benchmark.splits import REAL_DIR, REAL_STYLES, SPLITS, RealDensity, split_density, split_pairs
from mistyle.data.heldout import held_out_styles

ROOT = Path(__file__).resolve().parent.parent
RECORD = tomllib.loads((REAL_DIR / "SOURCES.toml").read_text())
OPEN_LICENCES = {"CC0-1.0", "CC-BY-4.0", "CC-BY-SA-3.0", "CC-BY-SA-4.0", "MIT", "BSD-3-Clause", "Apache-2.0"}
OPEN_LICENCES.add("LicenseRef-TOST-1.0")  # OpenUSD's: Apache 2.0 with another trademark section


def test_the_split_pairs_every_real_density_with_seven_held_out_styles():
    densities = SPLITS["real"].densities
    assert 4 <= len(densities) <= 8
    assert all(isinstance(spec, RealDensity) for spec in densities)
    assert {spec.kind for spec in densities} == {"dense", "thin"}  # a thick cloud and smoke, both
    assert [spec.name for spec in densities] == list(RECORD)
    assert set(REAL_STYLES) <= set(held_out_styles()) and len(set(REAL_STYLES)) == 7
    pairs = split_pairs("real")
    assert pairs == [(spec, style) for spec in densities for style in REAL_STYLES]
    assert [style for _, style in split_pairs("real", ["wdas_cloud"], ["hokusai_great_wave"])] == ["hokusai_great_wave"]


@pytest.mark.parametrize("spec", SPLITS["real"].densities, ids=lambda spec: spec.name)
def test_each_real_density_loads_finite_non_negative_and_at_most_128_a_side(spec):
    stored = np.load(spec.path())["density"]
    assert stored.dtype == np.float16
    density = split_density(spec)
    assert density.dtype == np.float32 and density.ndim == 3
    assert density.shape == spec.shape == tuple(RECORD[spec.name]["stored"]["shape_zyx"])
    assert max(density.shape) <= 128 and min(density.shape) >= 8
    assert np.isfinite(density).all() and density.min() >= 0.0
    assert density.max() == 1.0 and (density > 0).mean() > 0.01  # normalised, not empty
    assert not density[[0, -1]].any() and not density[:, [0, -1]].any() and not density[:, :, [0, -1]].any()
    # The file is the one the record describes (scripts/make_real_split.py writes both).
    assert (
        hashlib.sha256(np.ascontiguousarray(stored).tobytes()).hexdigest()
        == RECORD[spec.name]["stored"]["density_sha256"]
    )


@pytest.mark.parametrize("name", list(RECORD))
def test_sources_name_each_file_s_repository_commit_path_licence_and_author(name):
    entry = RECORD[name]
    assert (REAL_DIR / entry["file"]).is_file()
    assert re.fullmatch(r"[\w.-]+/[\w.-]+", entry["repo"])
    assert re.fullmatch(r"[0-9a-f]{40}", entry["commit"])
    assert re.fullmatch(r"[0-9a-f]{64}", entry["source_sha256"])
    assert entry["path"] and entry["author"] and entry["licence_note"] and entry["description"]
    assert entry["licence"] in OPEN_LICENCES
    assert entry["url"].startswith(f"https://github.com/{entry['repo']}/blob/{entry['commit']}/")
    assert entry["kind"] in ("dense", "thin")
    assert (entry["stored"]["occupancy"] >= 0.05) == (entry["kind"] == "dense")  # SOURCES.toml's rule


def test_every_real_file_is_recorded_and_shipped_as_package_data():
    files = {entry["file"] for entry in RECORD.values()}
    assert {path.name for path in REAL_DIR.glob("*.npz")} == files
    patterns = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["mistyle"]
    for file in [*files, "SOURCES.toml", "README.md"]:
        assert (REAL_DIR / file).is_file()
        assert any(fnmatch.fnmatch(f"benchmark/real/{file}", pattern) for pattern in patterns), file
    assert sum((REAL_DIR / file).stat().st_size for file in files) < 6_000_000  # the repository stays small
