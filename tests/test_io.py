"""Files: EXR and PNG round trips, atomic writes."""

import os

import numpy as np
import pytest

from mistyle.files import atomic_output, linear_to_srgb, read_exr, write_exr, write_png


def test_exr_round_trip_is_lossless(tmp_path):
    image = np.random.default_rng(0).random((5, 7, 3)).astype(np.float32) * 10
    np.testing.assert_array_equal(read_exr(write_exr(tmp_path / "a.exr", image)), image)


def test_png_is_a_valid_srgb_png(tmp_path):
    from PIL import Image

    image = np.linspace(0, 1, 4 * 6 * 3, dtype=np.float32).reshape(4, 6, 3)
    path = write_png(tmp_path / "a.png", image)
    with Image.open(path) as png:
        decoded = np.asarray(png)
    np.testing.assert_array_equal(decoded, np.round(linear_to_srgb(image) * 255).astype(np.uint8))
    assert oct(os.stat(path).st_mode & 0o777) != oct(0o600)  # not mkstemp's private mode


def test_failed_write_leaves_nothing_behind(tmp_path):
    with pytest.raises(RuntimeError):
        with atomic_output(tmp_path / "frame.npz") as tmp:
            tmp.write_bytes(b"half")
            raise RuntimeError("interrupted")
    assert list(tmp_path.iterdir()) == []


def test_unwritable_directory_names_the_fix(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(OSError, match="writable output directory"):
        write_png(blocker / "sub" / "a.png", np.zeros((2, 2, 3), np.float32))


def test_vol_files_with_impossible_headers_name_the_file(tmp_path):
    import struct

    from mistyle.files import read_vol

    path = tmp_path / "bad.vol"
    path.write_bytes(struct.pack("<3sBiiiii6f", b"VOL", 3, 1, -4, 4, 4, 1, 0, 0, 0, 1, 1, 1) + bytes(64))
    with pytest.raises(ValueError, match="bad.vol.*every size must be >= 1"):
        read_vol(path)


def test_foreign_checkpoints_never_get_the_advice_to_unpickle_them(tmp_path):
    import pickle

    from mistyle.model.checkpoint import load_checkpoint

    path = tmp_path / "evil.pt"
    with open(path, "wb") as handle:  # a pickle that would run code (os.getcwd) if unpickled freely
        pickle.dump({"format": 1, "model": os.getcwd}, handle)
    with pytest.raises(ValueError) as error:
        load_checkpoint(path)
    assert "weights_only" not in str(error.value) and "only checkpoints written by mistyle" in str(error.value)
    with pytest.raises(ValueError, match="No checkpoint file"):
        load_checkpoint(tmp_path / "nowhere.pt")


def test_a_transparent_style_is_refused_and_an_animated_one_is_named(tmp_path):
    from PIL import Image

    from mistyle.files import load_style

    Image.fromarray(np.zeros((16, 16, 4), np.uint8), "RGBA").save(tmp_path / "clear.png")
    with pytest.raises(ValueError, match="fully transparent"):
        load_style(tmp_path / "clear.png")
    frames = [Image.fromarray(np.full((16, 16, 3), value, np.uint8)) for value in (40, 200)]
    frames[0].save(tmp_path / "moving.gif", save_all=True, append_images=frames[1:])
    notes = []
    load_style(tmp_path / "moving.gif", notes)
    assert any("animated image of 2 frames; its first frame is the style" in note for note in notes)
