"""mistyle's files in Blender itself (``make test-blender``: Blender 5.3 as the ``bpy`` wheel, Python 3.13).

Kept out of ``make test`` (marker ``blender``): it needs the ~430 MB wheel in an environment of its own,
``.venv-blender`` (``scripts/setup_blender.sh``), named to these tests by ``$MISTYLE_BLENDER_PYTHON``.

* The Blender recipe of docs/usage.md, done as written, renders mistyle's ``volume.vdb`` (``--up z``) with Cycles on
  the CPU like mistyle's own path tracer from the same camera: luminance correlation >= 0.95,
  foreground IoU >= 0.85, mean foreground colour within 0.05 (display values);
* the plume is upright: the density's mass along Blender's world Z is mistyle's along its up axis;
* the add-on, built and installed from its zip, adds the stylized volume wired and in place, which
  renders like mistyle's; a bad input is an error in Blender's UI and adds nothing;
* ``.vdb`` files round-trip bit for bit between OpenVDB 10 (Debian's) and 13 (the wheel's), metadata kept.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.blender

ROOT = Path(__file__).resolve().parent.parent
BLENDER_PYTHON = os.environ.get("MISTYLE_BLENDER_PYTHON")
if BLENDER_PYTHON:
    BLENDER_PYTHON = os.path.abspath(BLENDER_PYTHON)  # not resolved: a venv's python is a link to its base
BLENDER_SIDE = Path(__file__).with_name("blender") / "blender_side.py"
STYLE = ROOT / "mistyle" / "data" / "heldout_styles" / "hokusai_great_wave.jpg"
DENSITY = ROOT / "examples" / "smoke_64.vol"
MANTAFLOW = ROOT / "tests" / "data" / "mantaflow"  # a real Blender cache, cut down (tests/data/SOURCES.toml)
RES, SPP, BLENDER_SPP = 96, 256, 256
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])

if not BLENDER_PYTHON:
    pytest.skip("set MISTYLE_BLENDER_PYTHON (make test-blender does) to run Blender's tests", allow_module_level=True)


def mistyle_render(*arguments: str) -> None:
    command = [sys.executable, "-m", "mistyle.render_final", *arguments, "--quiet"]
    result = subprocess.run(command, capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stderr


def in_blender(command: str, job: dict, tmp: Path) -> dict:
    job = dict(job, result=str(tmp / f"{command}_result.json"))
    job_file = tmp / f"{command}_job.json"
    job_file.write_text(json.dumps(job))
    environment = {key: value for key, value in os.environ.items() if key not in ("PYTHONPATH", "PYTHONHOME")}
    result = subprocess.run(
        [BLENDER_PYTHON, str(BLENDER_SIDE), command, str(job_file)],
        capture_output=True,
        text=True,
        env=environment,
        cwd=tmp,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return json.loads(Path(job["result"]).read_text())


def read_blender_exr(path) -> np.ndarray:
    import OpenEXR

    channels = OpenEXR.File(str(path)).channels()
    if "RGBA" in channels:
        return np.asarray(channels["RGBA"].pixels, np.float32)[..., :3]
    return np.stack([np.asarray(channels[c].pixels, np.float32) for c in "RGB"], axis=-1)


def agreement(mistyle_exr, blender_exr) -> dict:
    """Luminance correlation over either image's foreground, foreground IoU and the mean foreground
    colour of each, in mistyle's display space."""
    from mistyle.conventions import FOREGROUND_THRESHOLD
    from mistyle.files import read_exr
    from mistyle.tone import display

    ours, theirs = read_exr(mistyle_exr)[..., :3], read_blender_exr(blender_exr)
    shown_ours, shown_theirs = display(ours), display(theirs)
    fg_ours, fg_theirs = ours.max(-1) > FOREGROUND_THRESHOLD, theirs.max(-1) > FOREGROUND_THRESHOLD
    either = fg_ours | fg_theirs
    return {
        "correlation": float(np.corrcoef(shown_ours[either] @ LUMINANCE, shown_theirs[either] @ LUMINANCE)[0, 1]),
        "iou": float((fg_ours & fg_theirs).sum() / either.sum()),
        "colour_difference": float(np.abs(shown_ours[fg_ours].mean(0) - shown_theirs[fg_theirs].mean(0)).max()),
    }


@pytest.fixture(scope="module")
def rendered(tmp_path_factory) -> Path:
    """mistyle's feed-forward output of the bundled smoke in a held-out painting, for Blender (``--up z``)."""
    out = tmp_path_factory.mktemp("blender") / "out"
    mistyle_render(
        "--density", str(DENSITY), "--style", str(STYLE), "--refine", "0", "--vdb", "--up", "z",
        "--res", str(RES), "--spp", str(SPP), "--out", str(out),
    )  # fmt: skip
    return out


def render_job(rendered: Path, tmp: Path, image: str) -> dict:
    from mistyle.conventions import DEFAULT_ENV_RADIANCE

    return {
        "scene_xml": str(rendered / "scene.xml"),
        "radiance": DEFAULT_ENV_RADIANCE,
        "res": RES,
        "spp": BLENDER_SPP,
        "image": str(tmp / image),
    }


def test_readme_recipe_renders_like_mistyle(rendered, tmp_path):
    from mistyle.files.vdb import vdb_info

    metadata = vdb_info(rendered / "volume.vdb")["file_metadata"]
    assert metadata["mistyle_up_axis"] == "z"
    job = dict(
        render_job(rendered, tmp_path, "recipe.exr"),
        vdb=str(rendered / "volume.vdb"),
        world_density_scale=metadata["mistyle_world_density_scale"],
    )
    answer = in_blender("recipe", job, tmp_path)
    assert answer["grids"] == ["Cd", "density"]
    scores = agreement(rendered / "final.exr", tmp_path / "recipe.exr")
    print("Blender recipe:", json.dumps(scores))
    assert scores["correlation"] >= 0.95
    assert scores["iou"] >= 0.85
    assert scores["colour_difference"] <= 0.05


def test_plume_is_upright_in_blender(rendered, tmp_path):
    """Mass along Blender's world z is mistyle's along its up axis (y), and differs from the other axes'."""
    from mistyle.files import load_density

    answer = in_blender("profile", {"vdb": str(rendered / "volume.vdb")}, tmp_path)
    assert answer["openvdb"][0] == 13
    density = load_density(DENSITY)
    nonzero = lambda profile: np.asarray(profile)[np.asarray(profile) > 0]  # noqa: E731
    along_up = density.sum(axis=(0, 2))  # (Z, Y, X): mistyle's y
    blender_z = np.asarray(answer["profiles"]["z"])
    np.testing.assert_allclose(blender_z, nonzero(along_up), rtol=1e-4)
    for other in ("x", "y"):
        profile = np.asarray(answer["profiles"][other])
        assert len(profile) != len(blender_z) or not np.allclose(profile, blender_z, rtol=1e-2)


def addon_job(tmp: Path) -> dict:
    """The add-on built into ``tmp``, and what ``blender_side.install_addon`` needs to install it."""
    build = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "build_blender_addon.py"), "--out", str(tmp)],
        capture_output=True,
        text=True,
        check=True,
    )
    return {
        "addon_zip": build.stdout.strip(),
        "addon_module": "bl_ext.user_default.mistyle",
        "command": str(Path(sys.executable).with_name("mistyle-render")),
        "addon_out": str(tmp / "addon_out") + os.sep,
    }


def test_addon_adds_a_wired_upright_volume(rendered, tmp_path):
    from mistyle.files.vdb import read_vdb

    job = dict(
        render_job(rendered, tmp_path, "addon.exr"),
        **addon_job(tmp_path),
        input_vdb=str(rendered / "volume.vdb"),
        style=str(STYLE),
        missing_style=str(tmp_path / "no_such_style.png"),
    )
    answer = in_blender("addon", job, tmp_path)
    print("add-on:", json.dumps(answer))
    assert answer["operator"] == ["FINISHED"] and len(answer["added"]) == 1
    assert answer["colour"] == [1.0, 1.0, 1.0, 1.0]
    assert (answer["colour_attribute"], answer["density_attribute"]) == ("Cd", "density")
    assert answer["density"] == pytest.approx(20.0) and answer["linked"] and answer["volume_bounces"] >= 16
    assert answer["matrix_equal"]
    # The same density and style through the add-on give the same albedo as mistyle-render's run.
    ours, _, _ = read_vdb(rendered / "volume.vdb", grid="Cd")
    theirs, _, _ = read_vdb(answer["filepath"], grid="Cd")
    np.testing.assert_array_equal(ours, theirs)
    scores = agreement(rendered / "final.exr", tmp_path / "addon.exr")
    print("add-on render:", json.dumps(scores))
    assert scores["correlation"] >= 0.95 and scores["iou"] >= 0.85 and scores["colour_difference"] <= 0.05
    assert "does not exist" in json.dumps(answer["bad_input"])
    assert answer["after_bad_input"] == 2  # the source and the one stylized volume: nothing more


def test_addon_stylizes_a_vdb_sequence_over_the_frame_range(rendered, tmp_path):
    import shutil

    cache = tmp_path / "cache"
    cache.mkdir()
    frames = [cache / f"fluid_data_{number:04d}.vdb" for number in (1, 2)]
    for frame in frames:
        shutil.copy(rendered / "volume.vdb", frame)
    job = dict(addon_job(tmp_path), frames=[str(frame) for frame in frames], style=str(STYLE))
    answer = in_blender("addon_sequence", job, tmp_path)
    print("add-on, sequence:", json.dumps(answer))
    assert answer["operator"] == ["FINISHED"] and len(answer["added"]) == 1
    assert answer["is_sequence"] and answer["frame_duration"] == 2
    assert answer["files"] == ["volume_frame0000.vdb", "volume_frame0001.vdb"]


def test_addon_stylizes_a_real_fluid_cache_and_its_frames_lie_on_the_source(tmp_path):
    """Blender's own Mantaflow cache (24 grids, an int32 'flags' among them; the smoke's box grows from
    11x9x28 to 51x71x29 voxels between the two frames) on a volume object moved off the origin: the
    stylized object's density lies where the source's does in Blender's world at every frame."""
    import shutil

    cache = tmp_path / "cache"
    cache.mkdir()
    frames = []
    for number, name in enumerate(("fluid_data_0001.vdb", "fluid_data_0010.vdb"), 1):
        frames.append(cache / f"fluid_data_{number:04d}.vdb")
        shutil.copy(MANTAFLOW / name, frames[-1])
    job = dict(addon_job(tmp_path), frames=[str(frame) for frame in frames], style=str(STYLE))
    answer = in_blender("addon_cache", job, tmp_path)
    print("add-on, fluid cache:", json.dumps(answer))
    assert answer["operator"] == ["FINISHED"] and len(answer["added"]) == 1
    assert [frame["stylized"]["file"] for frame in answer["frames"]] == ["volume_frame0000.vdb", "volume_frame0001.vdb"]
    for frame in answer["frames"]:
        source, stylized = frame["source"], frame["stylized"]
        voxel = source["voxel"]
        assert stylized["voxel"] == pytest.approx(voxel, rel=1e-4)
        assert source["translation"] == pytest.approx([1.5, -2.0, 0.5]) == stylized["translation"]
        assert np.allclose(stylized["centre"], source["centre"], atol=0.05 * voxel)
        assert np.allclose(stylized["low"], source["low"], atol=1e-3 * voxel)
        assert np.allclose(stylized["high"], source["high"], atol=1e-3 * voxel)
    sizes = [np.subtract(frame["source"]["high"], frame["source"]["low"]) for frame in answer["frames"]]
    assert np.all(sizes[1] > sizes[0] - 1e-6) and np.any(sizes[1] > 2 * sizes[0])  # the box grew


DEBIAN_PYTHON = "/usr/bin/python3"


@pytest.mark.parametrize(("writer", "reader"), [("debian", "blender"), ("blender", "debian")])
def test_vdb_round_trips_between_openvdb_10_and_13(writer, reader, tmp_path, monkeypatch):
    from mistyle.files import vdb, vdb_layout

    interpreters = {"debian": DEBIAN_PYTHON, "blender": BLENDER_PYTHON}
    versions = {}
    for name, python in interpreters.items():
        probe = subprocess.run([python, str(vdb.CONVERTER), "probe"], capture_output=True, text=True)
        if probe.returncode != 0:
            pytest.skip(f"{name}'s Python has no OpenVDB module: {probe.stderr.strip()}")
        versions[name] = json.loads(probe.stdout)["version"][0]
    assert versions == {"debian": 10, "blender": 13}
    rng = np.random.default_rng(7)
    density = rng.random((9, 11, 13)).astype(np.float32) * (rng.random((9, 11, 13)) > 0.3)
    albedo = rng.random((9, 11, 13, 3)).astype(np.float32) * (density > 0)[..., None]
    transform = vdb.VdbTransform.for_medium_box(density.shape, "z")
    metadata = vdb_layout.mistyle_metadata(
        transform, density.shape, density_scale=20.0, up="z", style="a style", checkpoint="skpn_cpu.pt"
    )
    monkeypatch.setenv(vdb.INTERPRETER_ENV, interpreters[writer])
    vdb.write_vdb(
        tmp_path / "v.vdb",
        transform,
        {vdb.DENSITY_GRID: density, vdb_layout.ALBEDO_GRID: albedo},
        metadata=metadata,
        grid_metadata=metadata,
    )
    monkeypatch.setenv(vdb.INTERPRETER_ENV, interpreters[reader])
    read = vdb.read_vdb_grid(tmp_path / "v.vdb")
    colour = vdb.read_vdb_grid(tmp_path / "v.vdb", vdb_layout.ALBEDO_GRID)
    np.testing.assert_array_equal(read.array, density)
    np.testing.assert_array_equal(colour.array, albedo)
    assert read.transform == transform
    assert read.file_metadata == metadata
    grids = vdb.vdb_info(tmp_path / "v.vdb")["grids"]
    for grid in grids:
        assert {key: grid["metadata"][key] for key in metadata} == metadata
    assert {grid["name"]: grid["class"] for grid in grids}[vdb.DENSITY_GRID] == "fog volume"
