"""Style images: formats, folders (DTD layout, corrupt files), crops and the offline set."""

import numpy as np
import pytest
from PIL import Image

from mistyle.data.styles import ImageFolder, material_texture, offline_style_set, random_crop, style_set_diversity
from mistyle.io import load_style


def save(path, array, mode=None):
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(array, mode=mode).save(path)
    return path


def test_image_formats_become_rgb_floats(tmp_path):
    rgba = np.zeros((16, 16, 4), np.uint8)
    rgba[..., 0], rgba[..., 3] = 200, 128
    image = load_style(save(tmp_path / "rgba.png", rgba))
    assert image.shape == (16, 16, 3) and image.dtype == np.float32
    assert image[0, 0, 0] == pytest.approx(200 / 255 * 128 / 255, abs=1e-3)  # over black
    gray = load_style(save(tmp_path / "gray.png", np.full((12, 10), 51, np.uint8)))
    assert gray.shape == (12, 10, 3) and np.allclose(gray, 0.2)
    deep = load_style(save(tmp_path / "deep.png", np.full((9, 9), 65535, np.uint16)))
    assert np.allclose(deep, 1.0)


@pytest.mark.parametrize("content,match", [(None, "at least 8x8"), (b"not an image", "not a readable image")])
def test_bad_images_raise(tmp_path, content, match):
    path = tmp_path / "bad.png"
    if content is None:
        save(path, np.zeros((1, 1, 3), np.uint8))
    else:
        path.write_bytes(content)
    with pytest.raises(ValueError, match=match):
        load_style(path)
    with pytest.raises(ValueError, match="does not exist"):
        load_style(tmp_path / "missing.jpg")


def test_dtd_style_folder_with_a_corrupt_file(tmp_path):
    rng = np.random.default_rng(0)
    for cls in ("banded", "dotted"):
        for index in range(10):
            save(tmp_path / "images" / cls / f"{cls}_{index}.jpg", (rng.random((20, 24, 3)) * 255).astype(np.uint8))
    (tmp_path / "images" / "dotted" / "broken.jpg").write_bytes(b"\xff\xd8 truncated")
    folder = ImageFolder(tmp_path)
    assert len(folder.paths) == 21
    train, held = folder.split(0.3)
    assert len(train) + len(held) == 21 and 0 < len(held) < 21
    assert folder.split(0.3) == (train, held)  # stable
    images = folder.load_all()
    assert len(images) == 20 and [p.name for p in folder.skipped] == ["broken.jpg"]


def test_empty_folder_is_refused(tmp_path):
    (tmp_path / "notes.txt").write_text("no images here")
    with pytest.raises(ValueError, match="No images"):
        ImageFolder(tmp_path)


def test_random_crop_scales_small_images_up():
    rng = np.random.default_rng(0)
    crop = random_crop(np.random.default_rng(1).random((40, 60, 3)).astype(np.float32), 128, rng)
    assert crop.shape == (128, 128, 3)
    assert random_crop(np.zeros((200, 300, 3), np.float32), 128, rng).shape == (128, 128, 3)


def test_offline_style_set_is_deterministic_and_diverse():
    styles = offline_style_set(size=32, crops_per_photo=1, palettes_per_texture=1, materials_each=1)
    again = offline_style_set(size=32, crops_per_photo=1, palettes_per_texture=1, materials_each=1)
    assert [n for n, _ in styles] == [n for n, _ in again]
    for (_, a), (_, b) in zip(styles, again):
        np.testing.assert_array_equal(a, b)
    assert all(image.shape == (32, 32, 3) and 0 <= image.min() and image.max() <= 1 for _, image in styles)
    summary = style_set_diversity(styles)
    assert summary["by_source"] == {"photo": 7, "texture": 3, "material": 7}
    assert summary["hue_coverage"] >= 0.5


def test_material_textures_differ_by_seed_and_kind():
    assert not np.array_equal(material_texture("marble", 32, 0), material_texture("marble", 32, 1))
    with pytest.raises(ValueError, match="Unknown material"):
        material_texture("plastic")


def test_no_held_out_style_is_a_training_style(tmp_path):
    from mistyle.train.dataset import StyleSet

    styles = StyleSet("offline", size=32)
    assert styles.val_names and not set(styles.val_names) & set(styles.train_names)
    # Held out by source variant: the last variant of every source, and no pixel-identical copies.
    sources = {name.rpartition("_")[0] for name in styles.train_names}
    assert {name.rpartition("_")[0] for name in styles.val_names} == sources
    train = styles.train.flatten(1)
    for image in styles.val.flatten(1):
        assert not (train == image).all(dim=1).any()

    rng = np.random.default_rng(0)
    for index in range(12):
        save(tmp_path / "folder" / f"style_{index}.png", (rng.random((16, 16, 3)) * 255).astype(np.uint8))
    folder = StyleSet(str(tmp_path / "folder"), size=16)
    assert folder.val_names and not set(folder.val_names) & set(folder.train_names)
    assert len(folder.val_names) + len(folder.train_names) == 12
