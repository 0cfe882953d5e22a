"""Style images: formats, folders (DTD layout, corrupt files), crops and the offline set."""

import numpy as np
import pytest
from PIL import Image

from mistyle.data.styles import (
    PAINTINGS_DIR,
    ImageFolder,
    material_texture,
    offline_style_set,
    random_crop,
    style_set_diversity,
)
from mistyle.files import load_style


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
    styles = offline_style_set(
        size=32, crops_per_photo=1, palettes_per_texture=1, materials_each=1, crops_per_painting=1
    )
    again = offline_style_set(
        size=32, crops_per_photo=1, palettes_per_texture=1, materials_each=1, crops_per_painting=1
    )
    assert [n for n, _ in styles] == [n for n, _ in again]
    for (_, a), (_, b) in zip(styles, again):
        np.testing.assert_array_equal(a, b)
    assert all(image.shape == (32, 32, 3) and 0 <= image.min() and image.max() <= 1 for _, image in styles)
    summary = style_set_diversity(styles)
    assert summary["by_source"] == {
        "photo": 7,
        "texture": 3,
        "material": 7,
        "painting": len(list(PAINTINGS_DIR.glob("*.jpg"))),
    }
    assert summary["hue_coverage"] >= 0.5


def test_material_textures_differ_by_seed_and_kind():
    assert not np.array_equal(material_texture("marble", 32, 0), material_texture("marble", 32, 1))
    with pytest.raises(ValueError, match="Unknown material"):
        material_texture("plastic")


def test_no_held_out_style_is_a_training_style(tmp_path):
    from mistyle.train.dataset import StyleSet

    styles = StyleSet("offline", size=32)
    assert styles.val_names and not set(styles.val_names) & set(styles.train_names)
    # Photos, textures, materials: the last variant of every source; paintings: whole pictures, every crop.
    sources = {name.rpartition("_")[0] for name in styles.train_names if not name.startswith("painting/")}
    assert {name.rpartition("_")[0] for name in styles.val_names if not name.startswith("painting/")} == sources
    train_paintings = {name.rpartition("_")[0] for name in styles.train_names if name.startswith("painting/")}
    val_paintings = {name.rpartition("_")[0] for name in styles.val_names if name.startswith("painting/")}
    assert val_paintings and train_paintings and not val_paintings & train_paintings
    assert len(val_paintings) < 0.25 * len(train_paintings)
    # The painting files the experiments score on agree with the split the trainer draws from.
    from mistyle.train.dataset import training_paintings, validation_paintings

    assert {f"painting/{path.stem}" for path in validation_paintings()} == val_paintings
    assert {f"painting/{path.stem}" for path in training_paintings()} == train_paintings
    train = styles.train.flatten(1)
    for image in styles.val.flatten(1):
        assert not (train == image).all(dim=1).any()

    rng = np.random.default_rng(0)
    for index in range(12):
        save(tmp_path / "folder" / f"style_{index}.png", (rng.random((16, 16, 3)) * 255).astype(np.uint8))
    folder = StyleSet(str(tmp_path / "folder"), size=16)
    assert folder.val_names and not set(folder.val_names) & set(folder.train_names)
    assert len(folder.val_names) + len(folder.train_names) == 12


def test_every_pillow_mode_reads_as_the_colours_it_shows(tmp_path):
    """Palette, CMYK, 1-bit, greyscale+alpha, 16-bit and premultiplied images: the RGB a viewer shows."""
    rng = np.random.default_rng(0)
    rgb = (rng.random((16, 16, 3)) * 255).astype(np.uint8)
    reference = Image.fromarray(rgb, "RGB")
    expected = rgb.astype(np.float32) / 255

    palette = reference.quantize(colors=256)  # mode P: indices into a colour table
    palette.save(tmp_path / "palette.png")
    shown = np.asarray(palette.convert("RGB"), np.float32) / 255
    np.testing.assert_allclose(load_style(tmp_path / "palette.png"), shown, atol=1e-6)
    assert not np.allclose(shown[..., 0], shown[..., 1])  # not read as grey

    reference.convert("CMYK").save(tmp_path / "cmyk.jpg", quality=100)
    cmyk = load_style(tmp_path / "cmyk.jpg")
    assert np.abs(cmyk - expected).mean() < 0.05 and cmyk.mean() > 0.2  # not black (K was once taken as alpha)

    Image.fromarray(rgb[..., 0] > 127).save(tmp_path / "bits.png")
    np.testing.assert_array_equal(load_style(tmp_path / "bits.png")[..., 1], (rgb[..., 0] > 127).astype(np.float32))

    grey_alpha = Image.fromarray(np.stack([rgb[..., 0], np.full((16, 16), 255, np.uint8)], -1), "LA")
    grey_alpha.save(tmp_path / "la.png")
    np.testing.assert_allclose(load_style(tmp_path / "la.png")[..., 2], expected[..., 0], atol=1e-6)

    transparent = palette.copy()
    transparent.info["transparency"] = 0
    transparent.save(tmp_path / "transparent.png", transparency=0)
    assert load_style(tmp_path / "transparent.png").shape == (16, 16, 3)


def test_embedded_colour_profiles_are_applied_and_broken_ones_noted(tmp_path):
    from PIL import ImageCms

    rgb = np.full((16, 16, 3), (200, 60, 30), np.uint8)
    image = Image.fromarray(rgb, "RGB")
    image.save(tmp_path / "tagged.png", icc_profile=ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes())
    np.testing.assert_allclose(load_style(tmp_path / "tagged.png"), rgb / 255, atol=2 / 255)

    image.save(tmp_path / "broken.png", icc_profile=b"not a profile")
    notes = []
    np.testing.assert_allclose(load_style(tmp_path / "broken.png", notes), rgb / 255, atol=1e-6)
    assert any("unreadable" in note for note in notes)


def test_exr_styles_are_read_with_the_display_curve(tmp_path):
    from mistyle.files import write_exr
    from mistyle.tone import display

    radiance = np.random.default_rng(2).random((12, 12, 3)).astype(np.float32) * 4
    notes = []
    style = load_style(write_exr(tmp_path / "sky.exr", radiance), notes)
    np.testing.assert_allclose(style, display(radiance), atol=1e-6)
    assert any("display curve" in note for note in notes)


def test_a_luminance_only_exr_is_a_grey_style(tmp_path):
    import OpenEXR

    from mistyle.tone import display

    luminance = np.random.default_rng(3).random((12, 12)).astype(np.float32) * 4
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"Y": luminance}).write(str(tmp_path / "grey.exr"))
    style = load_style(tmp_path / "grey.exr")
    np.testing.assert_allclose(style, display(np.repeat(luminance[..., None], 3, axis=-1)), atol=1e-6)


def test_huge_images_are_refused_before_decoding(tmp_path, monkeypatch):
    save(tmp_path / "big.png", np.zeros((64, 64, 3), np.uint8))
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 1000)  # 64 x 64 > 2 x 1000: Pillow's bomb error
    with pytest.raises(ValueError, match="safety limit"):
        load_style(tmp_path / "big.png")
