"""Smoke dataset generation: layout, manifest, determinism, resume, shards, crops, bad input."""

import json

import numpy as np
import pytest

from mistyle.data.__main__ import main as data_cli
from mistyle.data.generate import SmokeDatasetSpec, generate_smoke, load_frame

SPEC = dict(resolution=12, plumes=3, frames=6, keep_first=4, keep_last=6, directions=16)


def quiet(*args):
    pass


@pytest.fixture(scope="module")
def dataset(tmp_path_factory, mi):
    out = tmp_path_factory.mktemp("smoke")
    generate_smoke(SmokeDatasetSpec(**SPEC), out, log=quiet)
    return out


def test_layout_and_manifest(dataset):
    manifest = json.loads((dataset / "manifest.json").read_text())
    assert len(manifest["files"]) == 3 * 3 and len(manifest["pairs"]) == 3 * 2
    assert manifest["spec"]["seed"] == 0 and manifest["generator"].startswith("mistyle-smoke")
    frame = load_frame(dataset / manifest["files"][0]["path"])
    assert frame["density"].shape == (12, 12, 12) and frame["velocity"].shape == (12, 12, 12, 3)
    assert frame["ls"].shape == (12, 12, 12) and 0 < frame["ls"].min() <= frame["ls"].max() <= 1
    first, second = manifest["pairs"][0]
    assert load_frame(dataset / first)["frame"] + 1 == load_frame(dataset / second)["frame"]


def test_generation_is_deterministic_and_resumable(dataset, tmp_path, mi):
    again = tmp_path / "again"
    generate_smoke(SmokeDatasetSpec(**SPEC), again, log=quiet)
    for path in sorted(dataset.glob("plume*/*.npz")):
        a, b = load_frame(path), load_frame(again / path.relative_to(dataset))
        np.testing.assert_array_equal(a["density"], b["density"])
        np.testing.assert_array_equal(a["ls"], b["ls"])
    # Remove one frame: a re-run rewrites exactly that file, identically, and skips the rest.
    victim = again / "plume0001" / "frame0005.npz"
    victim.unlink()
    untouched = (again / "plume0000" / "frame0004.npz").stat().st_mtime_ns
    generate_smoke(SmokeDatasetSpec(**SPEC), again, log=quiet)
    assert (again / "plume0000" / "frame0004.npz").stat().st_mtime_ns == untouched
    np.testing.assert_array_equal(
        load_frame(victim)["velocity"], load_frame(dataset / "plume0001" / "frame0005.npz")["velocity"]
    )
    assert not list(again.rglob("*.tmp*"))


def test_shards_split_the_plumes(tmp_path, mi):
    for index in range(2):
        generate_smoke(SmokeDatasetSpec(**SPEC), tmp_path, shard=(index, 2), log=quiet)
    plumes = [json.loads((tmp_path / f"manifest.shard-{i}-of-2.json").read_text())["files"] for i in range(2)]
    assert {f["plume"] for f in plumes[0]} == {0, 2} and {f["plume"] for f in plumes[1]} == {1}


def test_crops_share_windows_across_frames(tmp_path, mi):
    spec = SmokeDatasetSpec(**{**SPEC, "plumes": 1, "crop": 8, "crops_per_frame": 2})
    generate_smoke(spec, tmp_path, log=quiet)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert len(manifest["files"]) == 3 * 2
    assert all(f["shape"] == [8, 8, 8] for f in manifest["files"])
    assert load_frame(tmp_path / "plume0000" / "frame0004_crop1.npz")["density"].shape == (8, 8, 8)
    assert all(a.split("_")[-1] == b.split("_")[-1] for a, b in manifest["pairs"])


def test_cli_rejects_bad_arguments(tmp_path, capsys):
    assert data_cli(["smoke", "--res", "12", "--frames", "6", "--keep", "5-9", "--out", str(tmp_path)]) == 2
    assert "kept frames" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        data_cli(["smoke", "--shard", "3/2", "--out", str(tmp_path)])


def test_damaged_frame_file_gives_a_clear_error(tmp_path):
    broken = tmp_path / "frame0001.npz"
    broken.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="not a readable mistyle frame"):
        load_frame(broken)


def test_fire_cli_writes_flame_frames(tmp_path):
    assert data_cli(["fire", "--res", "12", "--frames", "6", "--keep", "5-6", "--out", str(tmp_path)]) == 0
    frames = sorted(tmp_path.glob("frame*.npz"))
    assert [f.name for f in frames] == ["frame0005.npz", "frame0006.npz"]
    with np.load(frames[0]) as data:
        assert data["density"].shape == (12, 12, 12) and data["velocity"].shape == (12, 12, 12, 3)
        assert 0 <= data["density"].min() and data["density"].max() < 1


def test_tiny_dataset_is_quick_and_complete(tmp_path, mi):
    from mistyle.data.styles import ImageFolder
    from mistyle.data.tiny import make_tiny_dataset

    out = make_tiny_dataset(tmp_path / "tiny", log=quiet)
    manifest = json.loads((out / "smoke" / "manifest.json").read_text())
    assert len(manifest["files"]) == 8 and len(manifest["pairs"]) == 6
    assert len(ImageFolder(out / "styles").load_all()) == 6


def test_a_full_disk_leaves_no_half_written_frame(tmp_path, mi, monkeypatch, capsys):
    """The third frame's write fails with ENOSPC: two complete frames stay, nothing partial."""
    import errno

    import mistyle.data.generate as generate

    real_savez, calls = np.savez_compressed, {"count": 0}

    def savez_until_full(handle, **arrays):
        calls["count"] += 1
        if calls["count"] == 3:
            handle.write(b"partial")
            raise OSError(errno.ENOSPC, "No space left on device")
        real_savez(handle, **arrays)

    monkeypatch.setattr(generate.np, "savez_compressed", savez_until_full)
    status = data_cli(
        [
            "smoke",
            "--res",
            "12",
            "--plumes",
            "1",
            "--frames",
            "6",
            "--keep",
            "2-6",
            "--directions",
            "16",
            "--out",
            str(tmp_path),
        ]
    )
    assert status == 1 and "disk" in capsys.readouterr().err
    from mistyle.ownership import MANIFEST_FILE, read_manifest

    files = sorted(p.name for p in tmp_path.rglob("*") if p.is_file() and p.name != MANIFEST_FILE)
    assert files == ["frame0002.npz", "frame0003.npz"]  # no temporary leftovers, no manifest.json yet
    # The frames written are recorded as mistyle's, so that the next run completes the folder.
    assert sorted(read_manifest(tmp_path)["files"]) == ["plume0000/frame0002.npz", "plume0000/frame0003.npz"]
    for path in tmp_path.rglob("*.npz"):
        load_frame(path)
