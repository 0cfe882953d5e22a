"""The fidelity benchmark's held-out split: recorded once, complete, and never seen by training."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from mistyle.data.heldout import (
    HELD_OUT_DENSITIES,
    HELD_OUT_SEED_BASE,
    check_training_styles,
    file_digest,
    held_out_styles,
)
from mistyle.data.styles import PHOTOS, TEXTURES, ImageFolder, skimage_data_dir
from mistyle.io import load_style


def test_held_out_styles_are_recorded_with_source_and_licence():
    styles = held_out_styles()
    assert len(styles) >= 12
    kinds = [record["kind"] for record in styles.values()]
    assert kinds.count("painting") >= 6 and "photograph" in kinds and "texture" in kinds
    for name, record in styles.items():
        for key in ("title", "author", "source", "licence", "hues"):
            assert record.get(key), f"{name} lacks {key}"
        image = load_style(record["path"])
        assert min(image.shape[:2]) >= 128 and image.shape[2] == 3


def test_no_held_out_style_is_in_the_offline_training_set():
    held = {file_digest(record["path"]) for record in held_out_styles().values()}
    data = skimage_data_dir()
    training_files = [data / name for name in list(PHOTOS.values()) + list(TEXTURES.values())]
    assert not held & {file_digest(path) for path in training_files}

    # ...nor the same picture re-encoded: compare small thumbnails of every pair.
    def thumbnail(path):
        image = load_style(path)
        side = min(image.shape[:2])
        image = image[:side, :side]
        step = side // 16
        return image[: step * 16 : step, : step * 16 : step][:16, :16]

    for record in held_out_styles().values():
        ours = thumbnail(record["path"])
        for path in training_files:
            assert np.abs(ours - thumbnail(path)).mean() > 0.05, (record["file"], path.name)


def test_a_training_folder_with_a_held_out_style_is_refused(tmp_path):
    record = next(iter(held_out_styles().values()))
    shutil.copy(record["path"], tmp_path / "renamed.jpg")
    with pytest.raises(ValueError, match="held-out benchmark style"):
        ImageFolder(tmp_path)
    with pytest.raises(ValueError, match="training must never see it"):
        check_training_styles([tmp_path / "renamed.jpg"])


def test_held_out_densities_use_seeds_and_generators_training_does_not():
    from mistyle.data.tiny import TINY_SMOKE
    from mistyle.train.dataset import DATASET_SPECS

    assert {spec.kind for spec in HELD_OUT_DENSITIES} >= {"smoke", "pyroclastic"}
    assert {spec.resolution for spec in HELD_OUT_DENSITIES if spec.kind == "smoke"} >= {64, 128}
    assert all(spec.seed > HELD_OUT_SEED_BASE for spec in HELD_OUT_DENSITIES)
    assert all(spec.seed < HELD_OUT_SEED_BASE for spec in list(DATASET_SPECS.values()) + [TINY_SMOKE])
    assert len({spec.name for spec in HELD_OUT_DENSITIES}) == len(HELD_OUT_DENSITIES)


def test_training_paintings_are_recorded_and_kept_apart_from_the_held_out_set():
    import tomllib

    from mistyle.data.styles import PAINTINGS_DIR

    records = tomllib.loads((PAINTINGS_DIR / "SOURCES.toml").read_text())
    files = {path.name for path in PAINTINGS_DIR.glob("*.jpg")}
    assert files and files == {record["file"] for record in records.values()}
    held = held_out_styles()
    held_repos = {record["source"].split()[0] for record in held.values()}
    held_digests = {file_digest(record["path"]) for record in held.values()}
    for name, record in records.items():
        for key in ("title", "author", "source", "licence"):
            assert record.get(key), f"{name} lacks {key}"
        assert record["source"].split()[0] not in held_repos, f"{name} comes from a held-out style's repository"
        assert file_digest(PAINTINGS_DIR / record["file"]) not in held_digests
    check_training_styles(sorted(PAINTINGS_DIR.glob("*.jpg")))
