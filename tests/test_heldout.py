"""The fidelity benchmark's held-out split: recorded once, complete, and never seen by training."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from mistyle.data.heldout import (
    HELD_OUT_DENSITIES,
    HELD_OUT_SEED_BASE,
    VALIDATION_DENSITIES,
    check_training_styles,
    file_digest,
    held_out_styles,
    validation_styles,
)
from mistyle.data.styles import PHOTOS, TEXTURES, ImageFolder, skimage_data_dir
from mistyle.files import load_style


@pytest.mark.parametrize("styles_of", [held_out_styles, validation_styles])
def test_held_out_and_validation_styles_are_recorded_with_source_and_licence(styles_of):
    styles = styles_of()
    assert len(styles) >= 12
    kinds = [record["kind"] for record in styles.values()]
    assert kinds.count("painting") >= 6 and "photograph" in kinds and "texture" in kinds
    for name, record in styles.items():
        for key in ("title", "author", "source", "licence", "hues"):
            assert record.get(key), f"{name} lacks {key}"
        image = load_style(record["path"])
        assert min(image.shape[:2]) >= 128 and image.shape[2] == 3


def thumbnail(path):
    image = load_style(path)
    side = min(image.shape[:2])
    image = image[:side, :side]
    step = side // 16
    return image[: step * 16 : step, : step * 16 : step][:16, :16]


def test_no_held_out_style_is_in_the_offline_training_set():
    held = {file_digest(record["path"]) for record in held_out_styles().values()}
    data = skimage_data_dir()
    training_files = [data / name for name in list(PHOTOS.values()) + list(TEXTURES.values())]
    assert not held & {file_digest(path) for path in training_files}

    # ...nor the same picture re-encoded: compare small thumbnails of every pair.
    for record in held_out_styles().values():
        ours = thumbnail(record["path"])
        for path in training_files:
            assert np.abs(ours - thumbnail(path)).mean() > 0.05, (record["file"], path.name)


@pytest.mark.parametrize(
    "styles_of, what", [(held_out_styles, "held-out benchmark"), (validation_styles, "validation")]
)
def test_a_training_folder_with_a_held_out_or_validation_style_is_refused(tmp_path, styles_of, what):
    record = next(iter(styles_of().values()))
    shutil.copy(record["path"], tmp_path / "renamed.jpg")
    with pytest.raises(ValueError, match=f"the {what} style"):
        ImageFolder(tmp_path)
    with pytest.raises(ValueError, match="training must never see it"):
        check_training_styles([tmp_path / "renamed.jpg"])


def test_validation_styles_are_kept_apart_from_training_and_the_held_out_set_by_source():
    """Choosing checkpoints on the validation split says something about the held-out split only if it
    is drawn the same way: other pictures of the same kinds, from repositories neither set took from."""
    import tomllib

    from mistyle.data.styles import PAINTINGS_DIR

    validation = validation_styles()
    held = held_out_styles()
    training = tomllib.loads((PAINTINGS_DIR / "SOURCES.toml").read_text())

    def repository(record):
        return record["source"].split()[0]

    others = {repository(record) for record in list(held.values()) + list(training.values())}
    others_files = [record["path"] for record in held.values()] + sorted(PAINTINGS_DIR.glob("*.jpg"))
    others_files += [skimage_data_dir() / name for name in list(PHOTOS.values()) + list(TEXTURES.values())]
    digests = {file_digest(path) for path in others_files}
    thumbnails = [thumbnail(path) for path in others_files]
    assert {record["kind"] for record in validation.values()} == {record["kind"] for record in held.values()}
    for name, record in validation.items():
        assert repository(record) not in others, f"{name} comes from a training or held-out style's repository"
        assert file_digest(record["path"]) not in digests
        ours = thumbnail(record["path"])
        assert all(np.abs(ours - theirs).mean() > 0.05 for theirs in thumbnails), name


def test_held_out_densities_use_seeds_and_generators_training_does_not():
    from mistyle.data.tiny import TINY_SMOKE
    from mistyle.train.dataset import DATASET_SPECS

    assert {spec.kind for spec in HELD_OUT_DENSITIES} >= {"smoke", "pyroclastic"}
    assert {spec.resolution for spec in HELD_OUT_DENSITIES if spec.kind == "smoke"} >= {64, 128}
    assert all(spec.seed > HELD_OUT_SEED_BASE for spec in HELD_OUT_DENSITIES)
    assert all(spec.seed < HELD_OUT_SEED_BASE for spec in list(DATASET_SPECS.values()) + [TINY_SMOKE])
    assert len({spec.name for spec in HELD_OUT_DENSITIES}) == len(HELD_OUT_DENSITIES)


def test_validation_densities_are_the_held_out_kinds_from_seeds_of_their_own():
    from mistyle.benchmark.splits import SPLITS

    held = SPLITS["heldout"].densities
    assert {(spec.kind, spec.resolution) for spec in VALIDATION_DENSITIES} == {
        (spec.kind, spec.resolution) for spec in held
    }
    seeds = [spec.seed for spec in VALIDATION_DENSITIES]
    assert all(seed > HELD_OUT_SEED_BASE for seed in seeds)
    assert not set(seeds) & {spec.seed for spec in HELD_OUT_DENSITIES}
    assert not {spec.name for spec in VALIDATION_DENSITIES} & {spec.name for spec in HELD_OUT_DENSITIES}


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
