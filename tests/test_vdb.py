"""OpenVDB files: exact round trips, grid choice, sparsity, axis order and transforms, and the errors.

The binding runs under another interpreter (``mistyle.files.vdb``); tests that need it are skipped, with the
reason, on machines where none has it. References that do not go through mistyle's own code: a grid
written by the binding directly, and ``MediumBox`` for the medium-box transform.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mistyle.files import vdb, vdb_frames, vdb_layout
from mistyle.files.vdb import (
    VdbUnavailable,
    read_vdb,
    read_vdb_grid,
    vdb_info,
    write_vdb,
)
from mistyle.files.vdb_layout import ALBEDO_GRID, DENSITY_GRID, VdbTransform
from mistyle.scenes.box import MediumBox

try:
    VDB_PYTHON = vdb.vdb_interpreter()
    WHY_NO_VDB = ""
except VdbUnavailable as error:
    VDB_PYTHON, WHY_NO_VDB = None, str(error)

needs_vdb = pytest.mark.skipif(VDB_PYTHON is None, reason=f"no interpreter has OpenVDB's module: {WHY_NO_VDB}")
REPO = Path(__file__).resolve().parents[1]


def _run_binding(script: str, *args: str) -> None:
    """Run ``script`` with the OpenVDB binding directly (an independent writer of test files)."""
    code = "try:\n    import pyopenvdb as vdb\nexcept ImportError:\n    import openvdb as vdb\n" + script
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    subprocess.run([VDB_PYTHON, "-c", code, *args], check=True, env=env, capture_output=True)


def _rotated_transform(index_min=(-5, 7, 300)) -> VdbTransform:
    rng = np.random.default_rng(7)
    rotation = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    matrix = np.eye(4)
    matrix[:3, :3] = rotation @ np.diag([0.013, 0.021, 0.034])
    matrix[:3, 3] = [123.25, -5.5, 1000.125]
    return VdbTransform(matrix, index_min)


@pytest.fixture
def fields(rng):
    """A (Z, Y, X) = (16, 18, 20) density with empty margins and a dense albedo."""
    density = rng.random((16, 18, 20), dtype=np.float32)
    density[:3] = 0.0
    density[:, :, -4:] = 0.0
    density[5, 6, 7] = 0.0  # an isolated empty voxel inside the active region
    albedo = rng.uniform(0.05, 1.0, (16, 18, 20, 3)).astype(np.float32)
    return density, albedo


@pytest.fixture
def subprocess_route(monkeypatch):
    """Force the converter to run as a helper process, as it does from mistyle's own environment."""
    if VDB_PYTHON is None:
        pytest.skip(f"no interpreter has OpenVDB's module: {WHY_NO_VDB}")
    monkeypatch.setenv(vdb.INTERPRETER_ENV, VDB_PYTHON)


# ----------------------------------------------------------------------------- round trips
@needs_vdb
@pytest.mark.parametrize(
    "transform",
    [VdbTransform.for_medium_box((16, 18, 20)), _rotated_transform()],
    ids=["medium-box", "rotated-scaled-translated"],
)
def test_density_and_albedo_round_trip_bit_exactly(tmp_path, fields, transform, subprocess_route):
    density, albedo = fields
    path = write_vdb(
        tmp_path / "out" / "smoke.vdb",
        transform,
        {DENSITY_GRID: density, ALBEDO_GRID: albedo},
        metadata={"source": "test", "frames": 1},
    )
    array, read_transform, name = read_vdb(path)
    assert name == DENSITY_GRID and array.dtype == np.float32
    np.testing.assert_array_equal(array, density)  # same shape despite the empty margins, same bits
    assert read_transform.index_min == transform.index_min
    scale = np.abs(transform.matrix).max()
    assert np.abs(read_transform.matrix - transform.matrix).max() <= 1e-12 * scale

    colour, colour_transform, colour_name = read_vdb(path, grid=ALBEDO_GRID)
    assert colour_name == ALBEDO_GRID and colour.shape == albedo.shape
    np.testing.assert_array_equal(colour, albedo)
    assert colour_transform == read_transform

    info = vdb_info(path)
    assert info["file_metadata"]["source"] == "test" and info["file_metadata"]["frames"] == 1
    classes = {g["name"]: (g["type"], g["class"]) for g in info["grids"]}
    assert classes == {DENSITY_GRID: ("float", "fog volume"), ALBEDO_GRID: ("vec3s", "unknown")}


@needs_vdb
def test_zeros_stay_inactive(tmp_path, fields, subprocess_route):
    density, _ = fields
    path = write_vdb(tmp_path / "sparse.vdb", VdbTransform.for_medium_box(density.shape), {DENSITY_GRID: density})
    (grid,) = vdb_info(path)["grids"]
    assert grid["active_voxel_count"] == np.count_nonzero(density) < density.size
    # The active voxels' box: no empty z-slabs 0-2, no x-columns 16-19.
    assert grid["index_min"] == [0, 0, 3] and grid["index_max"] == [15, 17, 15]


@needs_vdb
def test_in_process_route_writes_what_the_helper_reads(tmp_path, subprocess_route):
    """Where the binding loads in-process (the system Python here), the converter runs without a subprocess."""
    script = (
        "import sys, numpy as np\n"
        "from mistyle.files import vdb\n"
        "assert vdb._find_route(None).in_process\n"
        "d = np.arange(4 * 5 * 6, dtype=np.float32).reshape(4, 5, 6) / 7\n"
        "vdb.write_vdb(sys.argv[1], vdb.VdbTransform.for_medium_box(d.shape), {'density': d})\n"
        "a, t, n = vdb.read_vdb(sys.argv[1])\n"
        "assert np.array_equal(a, d) and n == 'density'\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONHOME", vdb.INTERPRETER_ENV)}
    env["PYTHONPATH"] = str(REPO)
    result = subprocess.run(
        [VDB_PYTHON, "-c", script, str(tmp_path / "a.vdb")], check=False, env=env, capture_output=True, text=True
    )
    if result.returncode != 0 and "No module named 'mistyle" in result.stderr:
        pytest.skip("mistyle does not import under the OpenVDB interpreter")
    assert result.returncode == 0, result.stderr
    array, _, _ = read_vdb(tmp_path / "a.vdb")
    np.testing.assert_array_equal(array, np.arange(4 * 5 * 6, dtype=np.float32).reshape(4, 5, 6) / 7)


# ----------------------------------------------------------------------------- axis order, transform
@needs_vdb
def test_a_grid_written_by_the_binding_reads_at_the_right_zyx(tmp_path, subprocess_route):
    path = tmp_path / "foreign.vdb"
    _run_binding(
        "import sys\n"
        "grid = vdb.FloatGrid()\n"
        "grid.name = 'smoke'\n"
        "grid.transform = vdb.createLinearTransform(0.25)\n"
        "grid.transform.translate((1.0, 2.0, 3.0))\n"
        "access = grid.getAccessor()\n"
        "access.setValueOn((10, 20, 30), 1.5)\n"  # (i, j, k) = (x, y, z)
        "access.setValueOn((12, 21, 30), 2.5)\n"
        "access.setValueOn((10, 20, 34), 4.0)\n"
        "vdb.write(sys.argv[1], grids=[grid])\n",
        str(path),
    )
    array, transform, name = read_vdb(path)  # the only float grid, although not named 'density'
    assert name == "smoke"
    assert transform.index_min == (10, 20, 30)
    assert array.shape == (5, 2, 3)  # (Z, Y, X) of the active box (10..12, 20..21, 30..34)
    assert array[0, 0, 0] == 1.5 and array[0, 1, 2] == 2.5 and array[4, 0, 0] == 4.0
    assert np.count_nonzero(array) == 3
    np.testing.assert_array_equal(transform.voxel_size, [0.25, 0.25, 0.25])
    # The centre of voxel (12, 21, 30), i.e. array[0, 1, 2], at 0.25 * ijk + (1, 2, 3).
    np.testing.assert_allclose(transform.voxel_centre(2, 1, 0), [4.0, 7.25, 10.5], rtol=0, atol=1e-12)
    low, high = transform.world_bbox(array.shape)
    np.testing.assert_allclose(low, 0.25 * np.array([9.5, 19.5, 29.5]) + [1, 2, 3], atol=1e-12)
    np.testing.assert_allclose(high, 0.25 * np.array([12.5, 21.5, 34.5]) + [1, 2, 3], atol=1e-12)


@pytest.mark.parametrize("shape", [(16, 18, 20), (7, 3, 5), (1, 1, 1)])
def test_medium_box_transform_places_voxels_where_medium_box_does(shape):
    box, transform = MediumBox(shape), VdbTransform.for_medium_box(shape)
    z, y, x = shape
    for corner in [(0, 0, 0), (x - 1, y - 1, z - 1), (x // 2, 0, z - 1), (0, y - 1, z // 3)]:
        np.testing.assert_allclose(transform.voxel_centre(*corner), box.voxel_centre(*corner), rtol=0, atol=1e-15)
    low, high = transform.world_bbox(shape)
    np.testing.assert_allclose(low, box.bbox_min, atol=1e-15)
    np.testing.assert_allclose(high, box.bbox_max, atol=1e-15)
    np.testing.assert_allclose(transform.voxel_size, box.voxel_size, rtol=1e-15)


def test_transforms_validate_and_compare():
    transform = _rotated_transform()
    assert transform == VdbTransform(transform.matrix.copy(), transform.index_min)
    assert hash(transform) == hash(VdbTransform(transform.matrix.copy(), transform.index_min))
    with pytest.raises(ValueError, match="affine"):
        VdbTransform(np.ones((4, 4)))
    with pytest.raises(ValueError, match="singular"):
        VdbTransform(np.diag([1.0, 0.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="three integers"):
        VdbTransform(np.eye(4), (0.5, 0, 0))


# ----------------------------------------------------------------------------- choosing the grid
@pytest.fixture
def two_float_grids(tmp_path):
    path = tmp_path / "two.vdb"
    _run_binding(
        "import sys\n"
        "grids = []\n"
        "for name, value in (('heat', 1.0), ('smoke', 2.0)):\n"
        "    grid = vdb.FloatGrid()\n"
        "    grid.name = name\n"
        "    grid.getAccessor().setValueOn((1, 2, 3), value)\n"
        "    grids.append(grid)\n"
        "velocity = vdb.Vec3SGrid()\n"
        "velocity.name = 'vel'\n"
        "velocity.getAccessor().setValueOn((0, 0, 0), (1.0, 0.0, 0.0))\n"
        "vdb.write(sys.argv[1], grids=grids + [velocity])\n",
        str(path),
    )
    return path


@needs_vdb
def test_several_float_grids_and_no_density_ask_for_a_name(two_float_grids, subprocess_route):
    with pytest.raises(ValueError, match=r"several float grids \('heat' \(float\), 'smoke' \(float\)\).*grid"):
        read_vdb(two_float_grids)
    array, _, name = read_vdb(two_float_grids, grid="smoke")
    assert name == "smoke" and array.shape == (1, 1, 1) and array[0, 0, 0] == 2.0


@needs_vdb
def test_density_is_the_default_and_grid_picks_another(tmp_path, fields, subprocess_route):
    density, _ = fields
    heat = np.where(density > 0, 3.0, 0.0).astype(np.float32)
    transform = VdbTransform.for_medium_box(density.shape)
    path = write_vdb(tmp_path / "two.vdb", transform, {"heat": heat, DENSITY_GRID: density})
    assert read_vdb(path)[2] == DENSITY_GRID
    array, _, name = read_vdb(path, grid="heat")
    assert name == "heat"
    np.testing.assert_array_equal(array, heat)


@needs_vdb
def test_a_missing_grid_lists_the_grids_there_are(two_float_grids, subprocess_route):
    listed = r"'heat' \(float\), 'smoke' \(float\), 'vel' \(vec3s\)"
    with pytest.raises(ValueError, match=r"no grid named 'density'.*" + listed):
        read_vdb(two_float_grids, grid="density")


# ----------------------------------------------------------------------------- errors
@needs_vdb
def test_a_file_that_is_not_a_vdb_is_a_value_error(tmp_path, subprocess_route):
    path = tmp_path / "fake.vdb"
    path.write_bytes(b"not an OpenVDB file at all")
    with pytest.raises(ValueError, match="fake.vdb is not a readable OpenVDB file") as caught:
        read_vdb(path)
    assert "Traceback" not in str(caught.value)
    with pytest.raises(ValueError, match="does not exist"):
        read_vdb(tmp_path / "missing.vdb")


@needs_vdb
def test_a_truncated_vdb_is_refused_before_the_binding_reads_it(tmp_path, fields, subprocess_route):
    """OpenVDB trusts the sizes a file declares: a 7 KB cut of a file took a minute and 8-11 GB of memory in
    the binding before its error. The declared offsets are checked against the file's size first."""
    import time

    density, albedo = fields
    whole = write_vdb(
        tmp_path / "whole.vdb",
        VdbTransform.for_medium_box(density.shape),
        {DENSITY_GRID: density, ALBEDO_GRID: albedo},
        metadata={"note": "x" * 300},
    ).read_bytes()
    started = time.perf_counter()
    for length in (12, 100, 400, 7000, len(whole) // 2, len(whole) - 1):
        cut = tmp_path / f"cut{length}.vdb"
        cut.write_bytes(whole[:length])
        with pytest.raises(ValueError, match=f"cut{length}.vdb .*(truncated|not a readable)") as caught:
            read_vdb(cut)
        assert "\n" not in str(caught.value)
        with pytest.raises(ValueError, match="truncated|not a readable"):
            vdb_info(cut)
    assert time.perf_counter() - started < 2.0


@needs_vdb
def test_empty_grids_are_refused_on_read(tmp_path, subprocess_route):
    empty = np.zeros((4, 4, 4))
    path = write_vdb(tmp_path / "empty.vdb", VdbTransform.for_medium_box(empty.shape), {DENSITY_GRID: empty})
    with pytest.raises(ValueError, match="empty"):
        read_vdb(path)


@needs_vdb
def test_frustum_transforms_are_refused(tmp_path, subprocess_route):
    path = tmp_path / "frustum.vdb"
    _run_binding(
        "import sys\n"
        "grid = vdb.FloatGrid()\n"
        "grid.name = 'density'\n"
        "grid.getAccessor().setValueOn((1, 1, 1), 1.0)\n"
        "grid.transform = vdb.createFrustumTransform((0, 0, 0), (10, 10, 10), 0.5, 2.0, 0.1)\n"
        "vdb.write(sys.argv[1], grids=[grid])\n",
        str(path),
    )
    with pytest.raises(ValueError, match="non-linear"):
        read_vdb(path)


def test_bad_inputs_are_refused_before_writing(tmp_path):
    transform = VdbTransform.for_medium_box((4, 4, 4))
    good = np.ones((4, 4, 4), np.float32)
    with pytest.raises(ValueError, match="NaN or infinite"):
        write_vdb(tmp_path / "a.vdb", transform, {DENSITY_GRID: np.full((4, 4, 4), np.nan)})
    with pytest.raises(ValueError, match="share one voxel box"):
        write_vdb(tmp_path / "a.vdb", transform, {DENSITY_GRID: good, ALBEDO_GRID: np.ones((4, 4, 5, 3))})
    with pytest.raises(ValueError, match=r"\(Z, Y, X, 3\)"):
        write_vdb(tmp_path / "a.vdb", transform, {ALBEDO_GRID: np.ones((4, 4, 4, 4))})
    with pytest.raises(ValueError, match="VdbTransform"):
        write_vdb(tmp_path / "a.vdb", np.eye(4), {DENSITY_GRID: good})
    with pytest.raises(ValueError, match="metadata 'when'"):
        write_vdb(tmp_path / "a.vdb", transform, {DENSITY_GRID: good}, metadata={"when": [1, 2]})
    assert not (tmp_path / "a.vdb").exists()


@needs_vdb
def test_a_failed_write_leaves_nothing_behind(tmp_path, subprocess_route):
    blocker = tmp_path / "taken.vdb"
    blocker.mkdir()  # the target is a folder, so the final rename fails
    with pytest.raises(ValueError, match="Cannot write"):
        write_vdb(blocker, VdbTransform.for_medium_box((4, 4, 4)), {DENSITY_GRID: np.ones((4, 4, 4))})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken.vdb"] and not any(blocker.iterdir())


def test_converter_errors_are_one_line_without_traceback(tmp_path):
    if VDB_PYTHON is None:
        pytest.skip(f"no interpreter has OpenVDB's module: {WHY_NO_VDB}")
    (tmp_path / "bad.vdb").write_text("nope")
    result = subprocess.run(
        [VDB_PYTHON, str(vdb.CONVERTER), "read", str(tmp_path / "bad.vdb"), str(tmp_path)],
        check=False,
        capture_output=True,
        text=True,
    )
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("error: ")
    result = subprocess.run([VDB_PYTHON, str(vdb.CONVERTER), "frobnicate"], check=False, capture_output=True, text=True)
    assert result.returncode == 2 and result.stderr.startswith("error: ") and result.stderr.count("\n") == 1


def test_an_interpreter_without_openvdb_names_the_fix(tmp_path, monkeypatch):
    # An interpreter that cannot import the module: mistyle's own Python with nothing extra on its path
    # (it has numpy 2, so even a system-wide pyopenvdb would not load) -- wrapped so that it is certain.
    fake = tmp_path / "python-without-openvdb"
    fake.write_text(f"#!/bin/sh\nPYTHONPATH= exec {sys.executable} -c 'import no_such_openvdb_module'\n")
    fake.chmod(0o755)
    monkeypatch.setenv(vdb.INTERPRETER_ENV, str(fake))
    for action in (
        vdb.vdb_interpreter,
        lambda: write_vdb(tmp_path / "a.vdb", VdbTransform(np.eye(4)), {DENSITY_GRID: np.ones((2, 2, 2))}),
    ):
        with pytest.raises(VdbUnavailable, match="apt-get install python3-openvdb") as caught:
            action()
        assert vdb.INTERPRETER_ENV in str(caught.value) and "make setup" in str(caught.value)
    assert isinstance(caught.value, ValueError)
    assert not (tmp_path / "a.vdb").exists()


@pytest.mark.parametrize("up", ["y", "z"])
@pytest.mark.parametrize("vector", [False, True])
def test_upright_keeps_every_voxel_in_place_and_turns_up_to_y(up, vector, rng):
    """``upright``: the array's Y axis ends up along the world's up axis (a rotation, not a mirror), and
    each voxel's value stays at its world position, for axis-aligned and rotated, flipped transforms."""
    shape = (4, 5, 6, 3) if vector else (4, 5, 6)
    array = rng.random(shape).astype(np.float32)
    flipped = np.diag([0.1, 0.2, -0.3, 1.0])
    flipped[:3, 3] = [1.0, 2.0, 3.0]
    for transform in (VdbTransform(flipped, (2, 3, 4)), _rotated_transform((1, -2, 3))):
        turned, moved = vdb_layout.upright(array, transform, up)
        world_up = vdb_layout.up_axis_matrix(up)[:3, 1]
        axes = moved.matrix[:3, :3] / np.linalg.norm(moved.matrix[:3, :3], axis=0)
        assert np.argmax(np.abs(world_up @ moved.matrix[:3, :3])) == 1 and world_up @ axes[:, 1] > 0
        assert np.linalg.det(moved.matrix[:3, :3]) * np.linalg.det(transform.matrix[:3, :3]) > 0
        before = {
            tuple(np.round(transform.voxel_centre(x, y, z), 9)): array[z, y, x].tobytes()
            for z, y, x in np.ndindex(*shape[:3])
        }
        after = {
            tuple(np.round(moved.voxel_centre(x, y, z), 9)): turned[z, y, x].tobytes()
            for z, y, x in np.ndindex(*turned.shape[:3])
        }
        assert before == after


def test_upright_leaves_a_y_up_grid_alone_and_the_medium_box_turns_for_blender():
    array = np.ones((2, 3, 4), np.float32)
    transform = VdbTransform.for_medium_box(array.shape)
    assert vdb_layout.upright(array, transform, "y") == (array, transform)
    blender = VdbTransform.for_medium_box(array.shape, "z")
    np.testing.assert_array_equal(blender.matrix, vdb_layout.up_axis_matrix("z") @ transform.matrix)
    assert vdb_layout.upright(array, blender, "z")[1] is blender
    with pytest.raises(ValueError, match="up axis is one of y, z"):
        vdb_layout.up_axis_matrix("x")


def test_world_density_scale_is_per_world_unit():
    """A medium 10 world units across at mistyle's scale 20 has extinction 2 per world unit."""
    transform = VdbTransform(np.diag([10 / 64, 10 / 64, 10 / 64, 1.0]))
    metadata = vdb_layout.mistyle_metadata(
        transform, (32, 64, 16), density_scale=20.0, up="y", style="s", checkpoint="c"
    )
    assert metadata["mistyle_world_density_scale"] == pytest.approx(2.0)
    assert vdb_layout.recorded_up_axis(metadata) == "y" and vdb_layout.recorded_up_axis({}) == "y"
    assert vdb_layout.recorded_up_axis({"mistyle_up_axis": "Z"}) == "z"


def test_the_converter_names_its_binding(subprocess_route):
    result = subprocess.run([VDB_PYTHON, str(vdb.CONVERTER), "probe"], capture_output=True, text=True, check=True)
    import json

    found = json.loads(result.stdout)
    assert found["version"][0] >= 10 and "openvdb" in found["module"].lower()


# ----------------------------------------------------------------------------- files as DCCs write them
MANTAFLOW = REPO / "tests" / "data" / "mantaflow"  # a real Blender cache, cut down (tests/data/SOURCES.toml)


def test_a_mantaflow_cache_lists_every_grid_without_any_binding(tmp_path, monkeypatch, capsys):
    """The grids of a Blender Mantaflow cache, int32 'flags' among them, list from the file's header in
    Python: no OpenVDB module is asked (the interpreter named here does not even exist)."""
    monkeypatch.setenv(vdb.INTERPRETER_ENV, str(tmp_path / "no-such-python"))
    info = vdb_info(MANTAFLOW / "fluid_data_0001.vdb")
    grids = {grid["name"]: grid for grid in info["grids"]}
    assert list(grids) == ["velocity", "flags", "density", "temperature", "flame"]
    assert (info["version"], info["library_version"]) == (224, [8, 0])
    assert {name: (g["type"], g["class"], g["readable"]) for name, g in grids.items()} == {
        "velocity": ("vec3s", "staggered", True),
        "flags": ("int32", "unknown", False),
        "density": ("float", "fog volume", True),
        "temperature": ("float", "fog volume", True),
        "flame": ("float", "fog volume", True),
    }
    density = grids["density"]
    assert density["half_float"] and density["active_voxel_count"] == 1665
    assert (density["index_min"], density["index_max"]) == ([63, 115, 7], [73, 123, 34])  # 11 x 9 x 28
    assert density["map"] == "UniformScaleMap" and density["is_linear"]
    np.testing.assert_array_equal(density["matrix"], np.diag([0.8, 0.8, 0.8, 1.0]).astype(np.float32))
    assert density["metadata"]["file_base_resolution"] == [125, 125, 60]  # Blender's domain, in voxels
    assert grids["flame"]["active_voxel_count"] == 0 and grids["flame"]["index_min"] is None  # empty

    assert vdb.main([str(MANTAFLOW / "fluid_data_0001.vdb")]) == 0
    text = capsys.readouterr().out
    assert "flags: int32 (saved as half), class unknown, 937500 active voxels" in text
    assert "not read by mistyle" in text and "index box (63, 115, 7)..(73, 123, 34) (11x9x28)" in text
    assert vdb.main([str(tmp_path / "missing.vdb")]) == 2
    assert capsys.readouterr().err.startswith("error: VDB file") and not vdb.main([str(MANTAFLOW), "--json"])


@needs_vdb
def test_a_mantaflow_cache_reads_its_density_despite_grids_the_binding_cannot_read(subprocess_route):
    """Debian's OpenVDB 10 cannot read the cache's int32 'flags' grid, nor list a file that holds one;
    mistyle lists the grids itself and reads only the one it needs."""
    path = MANTAFLOW / "fluid_data_0001.vdb"
    array, transform, name = read_vdb(path)  # no --grid: 'density'
    assert name == DENSITY_GRID and array.shape == (28, 9, 11) and transform.index_min == (63, 115, 7)
    assert np.count_nonzero(array) == 1665 and 0.0 < array.max() <= 1.0
    np.testing.assert_array_equal(transform.voxel_size, [np.float32(0.8)] * 3)
    velocity, velocity_transform, _ = read_vdb(path, grid="velocity")
    assert velocity.shape == (26, 9, 11, 3) and velocity_transform.index_min == (63, 115, 9)
    assert read_vdb(path, grid="temperature")[0].shape == (28, 9, 11)
    with pytest.raises(ValueError, match=r"Grid 'flags' of .*fluid_data_0001.vdb holds int32 values; mistyle reads"):
        read_vdb(path, grid="flags")
    with pytest.raises(ValueError, match=r"no grid named 'smoke'; it holds 'velocity' \(vec3s\), 'flags' \(int32\)"):
        read_vdb(path, grid="smoke")


@needs_vdb
def test_without_a_float_grid_the_error_lists_the_grids(tmp_path, subprocess_route):
    path = tmp_path / "colour.vdb"
    _run_binding(
        "import sys\n"
        "grid = vdb.Vec3SGrid()\n"
        "grid.name = 'Cd'\n"
        "grid.getAccessor().setValueOn((0, 0, 0), (1.0, 0.5, 0.0))\n"
        "vdb.write(sys.argv[1], grids=[grid])\n",
        str(path),
    )
    with pytest.raises(ValueError, match=r"colour.vdb holds no float grid .*'Cd' \(vec3s\)"):
        read_vdb(path)


@needs_vdb
@pytest.mark.parametrize(
    "transform", [VdbTransform.for_medium_box((3, 4, 5)), _rotated_transform()], ids=["scale", "affine"]
)
def test_info_reads_transforms_and_metadata_bit_for_bit(tmp_path, transform, subprocess_route):
    """The transform and metadata that ``vdb_info`` reads in Python are what was written, to the bit."""
    density = np.ones((3, 4, 5), np.float32)
    metadata = {"text": "smoke", "count": 3, "scale": 0.1, "flag": True}
    path = write_vdb(tmp_path / "t.vdb", transform, {DENSITY_GRID: density}, metadata=metadata)
    (grid,) = vdb_info(path)["grids"]
    np.testing.assert_array_equal(np.array(grid["matrix"]).T, transform.matrix)
    np.testing.assert_array_equal(grid["voxel_size"], transform.voxel_size)
    assert vdb_info(path)["file_metadata"] == metadata
    assert vdb.read_vdb_grid(path).file_metadata == metadata


# ----------------------------------------------------------------------------- sequences in world space
VOXEL, ORIGIN = 0.1, (1.0, 2.0, 3.0)
MARK = (20, 21, 22)  # index (i, j, k) of a voxel at one world position in every frame, value 5
# Frames of a sphere that grows and moves: (centre (i, j, k), radius) in the first frame's index space,
# and whole voxels by which a frame's own index origin is moved (as an adaptive domain moves).
SPHERES = [((18, 20, 22), 2.0, (0, 0, 0)), ((21, 22, 21), 3.5, (0, 0, 0)), ((25, 19, 24), 4.5, (3, -2, 0))]


def _write_sphere_frames(folder: Path, frames=SPHERES, voxel=VOXEL) -> None:
    """One .vdb per frame, written by the binding itself, voxels set one by one."""
    folder.mkdir()
    _run_binding(
        "import sys, json, math\n"
        "frames, voxel, origin, mark = json.loads(sys.argv[1])\n"
        "for n, ((centre, radius, moved), size) in enumerate(zip(frames, voxel)):\n"
        "    grid = vdb.FloatGrid()\n"
        "    grid.name = 'density'\n"
        "    grid.transform = vdb.createLinearTransform(size)\n"
        "    grid.transform.translate(tuple(o + m * size for o, m in zip(origin, moved)))\n"
        "    access = grid.getAccessor()\n"
        "    r = int(math.ceil(radius))\n"
        "    for i in range(-r, r + 1):\n"
        "        for j in range(-r, r + 1):\n"
        "            for k in range(-r, r + 1):\n"
        "                if i * i + j * j + k * k <= radius * radius:\n"
        "                    ijk = (centre[0] + i - moved[0], centre[1] + j - moved[1], centre[2] + k - moved[2])\n"
        "                    access.setValueOn(ijk, 0.5)\n"
        "    access.setValueOn(tuple(m - d for m, d in zip(mark, moved)), 5.0)\n"
        "    vdb.write(sys.argv[2] + '/frame%04d.vdb' % n, grids=[grid])\n",
        json.dumps([frames, voxel if isinstance(voxel, list) else [voxel] * len(frames), ORIGIN, MARK]),
        str(folder),
    )


@needs_vdb
def test_a_sequence_whose_box_grows_and_moves_shares_one_world_aligned_box(tmp_path, subprocess_route):
    from mistyle.files import load_density_frames

    _write_sphere_frames(tmp_path / "seq")
    # The union of the frames' active boxes, in the first frame's index space (spheres and the mark).
    lows = [np.subtract(c, int(r)) for c, r, _ in SPHERES] + [np.array(MARK)]
    highs = [np.add(c, int(r)) for c, r, _ in SPHERES] + [np.array(MARK)]
    low, high = np.min(lows, axis=0), np.max(highs, axis=0)
    mark_world = VOXEL * np.array(MARK) + ORIGIN

    loaded = load_density_frames(tmp_path / "seq")
    assert {d.shape for d in loaded.densities} == {tuple((high - low + 1)[::-1])}
    marks = [tuple(np.argwhere(d == 5.0)[0]) for d in loaded.densities]  # [z, y, x]
    assert marks == [tuple((np.array(MARK) - low)[::-1])] * 3  # the same index in every frame
    for transform, (_, _, moved) in zip(loaded.transforms, SPHERES):
        # Index (0, 0, 0) is the union's corner voxel; the mark sits where it was written.
        np.testing.assert_allclose(transform.voxel_centre(0, 0, 0), VOXEL * low + ORIGIN, atol=1e-12)
        np.testing.assert_allclose(transform.voxel_centre(*marks[0][::-1]), mark_world, atol=1e-12)
        assert transform.index_min == tuple(low - moved)  # in the frame's own file's index space
    sums = [float(d.sum()) for d in loaded.densities]
    assert sums == [5.0 + 0.5 * (np.count_nonzero(d) - 1) for d in loaded.densities]  # nothing cut off

    # Written back with its transform, a frame drops onto the source: the mark at the same world place.
    out = write_vdb(tmp_path / "out.vdb", loaded.transforms[2], {DENSITY_GRID: loaded.densities[2]})
    array, transform, _ = read_vdb(out)
    z, y, x = np.argwhere(array == 5.0)[0]
    np.testing.assert_allclose(transform.voxel_centre(x, y, z), mark_world, atol=1e-12)

    # Blender's up axis: every frame turns the same way and still lines up.
    upright = load_density_frames(tmp_path / "seq", up="z")
    assert len({d.shape for d in upright.densities}) == 1
    turned = [tuple(np.argwhere(d == 5.0)[0]) for d in upright.densities]
    assert len(set(turned)) == 1
    for transform in upright.transforms:
        np.testing.assert_allclose(transform.voxel_centre(*turned[0][::-1]), mark_world, atol=1e-12)


@needs_vdb
def test_frames_on_different_lattices_are_refused(tmp_path, subprocess_route):
    from mistyle.files import load_density_frames

    frames = [((5, 5, 5), 1.0, (0, 0, 0))] * 2
    _write_sphere_frames(tmp_path / "sizes", frames, voxel=[0.1, 0.2])
    with pytest.raises(ValueError, match=r"frame0000.vdb and frame0001.vdb have different voxel sizes \(0.1 and 0.2\)"):
        load_density_frames(tmp_path / "sizes")


@needs_vdb
def test_a_real_mantaflow_sequence_loads_as_one_box(subprocess_route):
    """Frames 1 and 10 of the cache: the density's active box grows from 11x9x28 to 51x71x29."""
    from mistyle.files import load_density_frames

    first, _, _ = read_vdb(MANTAFLOW / "fluid_data_0001.vdb")
    notes = []
    loaded = load_density_frames(MANTAFLOW, notes=notes)
    # Frame 10 has no velocity grid (cut from the file), so the sequence has no velocities, and says why.
    assert loaded.velocities is None
    assert notes == [
        f"fluid_data_0010.vdb of {MANTAFLOW} carries no velocity, so the sequence is read without "
        "velocities: frames are not warped by their motion, and flicker is measured unwarped"
    ]
    assert [d.shape for d in loaded.densities] == [(29, 71, 51)] * 2  # index box (44, 53, 7)..(94, 123, 35)
    assert [t.index_min for t in loaded.transforms] == [(44, 53, 7)] * 2
    placed = loaded.densities[0][0:28, 115 - 53 : 124 - 53, 63 - 44 : 74 - 44]
    np.testing.assert_array_equal(placed, first)
    assert np.count_nonzero(loaded.densities[0]) == np.count_nonzero(first)  # nothing else in the margins
    blender = load_density_frames(MANTAFLOW, up="z")
    assert [d.shape for d in blender.densities] == [(71, 29, 51)] * 2


def _values_at_world(grid, centres):
    """``grid`` (a ``read_vdb_grid`` result) at world points ``(N, 3)`` that lie on its voxel centres."""
    index = np.linalg.solve(grid.transform.matrix[:3, :3], (centres - grid.transform.matrix[:3, 3]).T).T
    x, y, z = np.round(index - np.asarray(grid.transform.index_min)).astype(int).T
    return grid.array[z, y, x]


def test_a_mantaflow_cache_renders_end_to_end_and_its_temperature_travels(mi, tmp_path, subprocess_route):
    """``mistyle-render --density CACHE --up z`` on Blender's own cache: one volume VDB per frame, each with
    the source's 'temperature' beside the density and the stylized 'Cd', at the same world places."""
    from mistyle.render_final import main

    out = tmp_path / "out"
    style = REPO / "examples" / "style_marble.png"
    options = ["--up", "z", "--refine", "0", "--res", "16", "--spp", "1", "--quiet"]
    assert main(["--density", str(MANTAFLOW), "--style", str(style), "--out", str(out), *options]) == 0
    report = json.loads((out / "report.json").read_text())
    assert "the volume VDBs carry the input's 'temperature' (1 of 2 frames) grid(s)" in " ".join(report["notes"])
    # Frame 10 was cut to 'density' and an empty 'flame' (tests/data/SOURCES.toml): nothing to carry.
    frames = [("fluid_data_0001.vdb", ["density", "temperature"]), ("fluid_data_0010.vdb", ["density"])]
    for number, (name, grids) in enumerate(frames):
        written = out / f"volume_frame{number:04d}.vdb"
        assert [g["name"] for g in vdb_info(written)["grids"]] == ["density", "Cd", *grids[1:]]
        for grid_name in grids:
            source, ours = read_vdb_grid(MANTAFLOW / name, grid_name), read_vdb_grid(written, grid_name)
            z, y, x = np.nonzero(source.array)
            centres = source.transform.index_to_world(np.stack([x, y, z], -1) + np.asarray(source.transform.index_min))
            np.testing.assert_array_equal(_values_at_world(ours, centres), source.array[z, y, x])
            assert np.count_nonzero(ours.array) == len(z)  # nothing anywhere else


def test_frames_are_lined_up_by_whole_voxels_only():
    """``vdb_frames_in_one_box`` on its own: a frame whose origin is whole voxels away is padded into the
    union; a fraction of a voxel or a turned grid would need resampling, and is refused by name."""
    from mistyle.files import vdb_frames_in_one_box

    def frame(matrix, index_min, shape=(2, 3, 4)):
        return {"density": np.ones(shape, np.float32), "transform": VdbTransform(matrix, index_min), "up": "y"}

    base = np.diag([0.5, 0.5, 0.5, 1.0])
    moved = base.copy()
    moved[:3, 3] = [1.0, 0.0, -0.5]  # (2, 0, -1) voxels
    files = [Path("a.vdb"), Path("b.vdb")]
    first, second = vdb_frames_in_one_box(files, [frame(base, (0, 0, 0)), frame(moved, (0, 0, 0))])
    assert first["density"].shape == second["density"].shape == (3, 3, 6)  # x 0..5, y 0..2, z -1..1
    assert first["transform"].index_min == (0, 0, -1) and second["transform"].index_min == (-2, 0, 0)
    for placed in (first, second):
        np.testing.assert_array_equal(placed["transform"].voxel_centre(0, 0, 0), [0.0, 0.0, -0.5])
    assert first["density"][1:3, :, 0:4].all() and second["density"][0:2, :, 2:6].all()
    assert first["density"].sum() == second["density"].sum() == 24

    shifted = base.copy()
    shifted[0, 3] = 0.2
    with pytest.raises(ValueError, match=r"b.vdb's voxels are offset by a fraction of a voxel from a.vdb's"):
        vdb_frames_in_one_box(files, [frame(base, (0, 0, 0)), frame(shifted, (0, 0, 0))])
    turned = base @ vdb_layout.up_axis_matrix("z")
    with pytest.raises(ValueError, match="a.vdb and b.vdb are rotated against each other"):
        vdb_frames_in_one_box(files, [frame(base, (0, 0, 0)), frame(turned, (0, 0, 0))])


# ----------------------------------------------------------------------------- velocities
# A block of smoke that moves by whole voxels from frame 0 to frame 1, and a uniform velocity that says
# so, written by the binding in world units per second: (0, 2, 1) voxels per frame along (i, j, k) at
# voxel size 0.25 and 30 fps (the files' 'fps' metadata) is (0, 15, 7.5) world units per second.
MOTION_VOXELS, MOTION_FPS, MOTION_SIZE = (0, 2, 1), 30.0, 0.25
BLOCK = (10, 20, 30)  # the block's low corner (i, j, k) in frame 0


def _write_moving_block(folder: Path) -> None:
    folder.mkdir()
    world_per_second = [v * MOTION_SIZE * MOTION_FPS for v in MOTION_VOXELS]
    _run_binding(
        "import sys, json\n"
        "corner, step, velocity, size, fps = json.loads(sys.argv[1])\n"
        "for frame in range(2):\n"
        "    density = vdb.FloatGrid()\n"
        "    density.name = 'density'\n"
        "    access = density.getAccessor()\n"
        "    for n in range(27):\n"  # 27 distinct values, so that a wrong shift cannot match
        "        i, j, k = n % 3, n // 3 % 3, n // 9\n"
        "        at = tuple(c + d + frame * s for c, d, s in zip(corner, (i, j, k), step))\n"
        "        access.setValueOn(at, 0.1 + n / 30)\n"
        "    vel = vdb.Vec3SGrid()\n"
        "    vel.name = 'vel'\n"
        "    low = tuple(c - 3 for c in corner)\n"
        "    vel.fill(low, tuple(c + 6 for c in corner), tuple(velocity), True)\n"
        "    for grid in (density, vel):\n"
        "        grid.transform = vdb.createLinearTransform(size)\n"
        "        grid.transform.translate((1.0, 2.0, 3.0))\n"
        "    vdb.write(sys.argv[2] + '/block%04d.vdb' % frame, grids=[density, vel], metadata={'fps': fps})\n",
        json.dumps([BLOCK, MOTION_VOXELS, world_per_second, MOTION_SIZE, MOTION_FPS]),
        str(folder),
    )


def _inside_after_warp(velocity: np.ndarray) -> tuple:
    """The part of a grid where ``x - velocity`` (uniform, whole voxels) stays inside it: what the warp
    can predict without reading its clamped border."""
    shift = velocity.reshape(-1, 3)[0].round().astype(int)[::-1]  # (z, y, x)
    return tuple(slice(max(d, 0), None if d >= 0 else d) for d in shift)


@needs_vdb
def test_vdb_velocities_are_voxels_per_frame_along_the_axes_mistyle_renders(tmp_path, subprocess_route):
    """A file's velocity in world units per second reads as the voxels per frame of ``mistyle.warp``,
    components along the array's (x, y, z); with Blender's up axis the components turn with the voxels;
    and warping frame 0 by its velocity gives frame 1, which is what the temporal terms rely on."""
    from mistyle.files import load_density_frames
    from mistyle.warp import warp_grid

    _write_moving_block(tmp_path / "seq")
    # up y: the file's (i, j, k) are the array's (x, y, z). up z: the file's k (world up) becomes the
    # array's y and its j the array's -z (vdb_layout.upright), so (0, 2, 1) along (i, j, k) reads as (0, 1, -2).
    for up, expected in ((None, (0.0, 2.0, 1.0)), ("z", (0.0, 1.0, -2.0))):
        notes = []
        loaded = load_density_frames(tmp_path / "seq", up=up, notes=notes)
        assert loaded.velocities is not None and len(loaded.velocities) == 2
        for density, velocity in zip(loaded.densities, loaded.velocities):
            assert velocity.shape == density.shape + (3,) and velocity.dtype == np.float32
            np.testing.assert_allclose(velocity.reshape(-1, 3), np.tile(expected, (density.size, 1)), atol=1e-6)
        assert notes == [
            f"{tmp_path / 'seq'}: velocity from grid 'vel', in world units per second, at 30 fps "
            "(the file's 'fps' metadata)"
        ]
        first, second = loaded.densities
        inside = _inside_after_warp(loaded.velocities[0])
        assert np.count_nonzero(second[inside]) == 27  # the whole block lies where the warp can predict it
        np.testing.assert_allclose(warp_grid(first, loaded.velocities[0])[inside], second[inside], atol=1e-5)
        assert np.abs(first - second).sum() > 1.0  # they do differ unwarped

    # The frame rate given wins over the file's: at 24 fps each frame lasts 30/24 times as long.
    frame = vdb_frames.read_vdb_frame(tmp_path / "seq" / "block0000.vdb", velocity_grid="vel", fps=24)
    assert (frame.velocity.source.fps, frame.velocity.source.fps_from) == (24.0, "given")
    steps = vdb_frames.world_to_index(frame.velocity.at(frame.density.transform, (3, 3, 3)), frame.density.transform)
    np.testing.assert_allclose(steps.reshape(-1, 3), np.tile(MOTION_VOXELS, (27, 1)) * 30 / 24, rtol=1e-6)


def test_velocities_are_sampled_at_the_density_voxels_through_both_transforms():
    """No binding: a staggered grid is averaged to cell centres, a grid on a coarser, shifted lattice is
    sampled trilinearly (exact for a linear field), and the units follow what the grid says."""
    from mistyle.files.vdb import VdbGrid
    from mistyle.files.vdb_frames import VelocitySource, _velocity_per_frame

    density = VdbTransform(np.diag([0.5, 0.5, 0.5, 1.0]), (4, 5, 6))
    shape = (6, 5, 4)  # (Z, Y, X): index box (4..7, 5..9, 6..11)

    # Staggered, in the grid's own cells per solver time unit (Mantaflow): the x faces of voxel i hold i.
    faces = np.zeros((8, 7, 6, 3), np.float32)
    faces[..., 0] = np.arange(6)[None, None, :] + 3.0  # index_min i = 3: face values i
    mac = VdbGrid(faces, VdbTransform(density.matrix, (3, 4, 5)), "velocity", {})
    source = VelocitySource("f.vdb", ("velocity",), True, "mantaflow", 25.0, "given")
    world = _velocity_per_frame(source, [mac], density, shape)
    # The centre of voxel i lies between faces i and i + 1: (2i + 1) / 2 cells per solver unit, 0.1 solver
    # units per frame (2.5 / 25 fps), 0.5 world units per cell; voxel i = 8 has no face i + 1 = 9 (zero).
    i = np.arange(4, 8)
    expected = np.where(i + 1 <= 8, (2 * i + 1) / 2, i / 2) * 0.1 * 0.5
    np.testing.assert_allclose(world[0, 0, :, 0], expected, rtol=1e-6)
    assert not world[..., 1:].any()

    # A coarser (voxel 1.0), shifted lattice in world units per second: a linear field, sampled exactly.
    coarse = np.diag([1.0, 1.0, 1.0, 1.0])
    coarse[:3, 3] = [0.25, -0.5, 0.75]
    centres = VdbTransform(coarse, (-2, -2, -2)).index_to_world(
        np.stack(np.meshgrid(*[np.arange(-2, 10)] * 3, indexing="ij"), axis=-1).transpose(2, 1, 0, 3) + 0.0
    )  # (z, y, x, 3) world centres of the coarse voxels
    field = np.stack([centres[..., 0] + 2 * centres[..., 2], -centres[..., 1], 0.5 + 0 * centres[..., 0]], -1)
    grid = VdbGrid(field.astype(np.float32), VdbTransform(coarse, (-2, -2, -2)), "vel", {})
    sampled = _velocity_per_frame(
        VelocitySource("f.vdb", ("vel",), False, "world", 2.0, "given"), [grid], density, shape
    )
    z, y, x = np.meshgrid(*[np.arange(n) for n in shape], indexing="ij")
    where = density.index_to_world(np.stack([x, y, z], -1) + np.array(density.index_min))
    truth = np.stack([where[..., 0] + 2 * where[..., 2], -where[..., 1], 0.5 + 0 * where[..., 0]], -1) / 2.0
    np.testing.assert_allclose(sampled, truth, atol=1e-5)


def test_the_velocity_grid_is_found_by_name_and_its_units_by_its_metadata():
    """No binding: ``find_velocity`` on scans like Blender's, Houdini's and others' files."""
    from mistyle.files.vdb_frames import find_velocity

    def scan(*grids, **file_metadata):
        return {
            "grids": [{"name": n, "type": t, "class": c, "metadata": m} for n, t, c, m in grids],
            "file_metadata": file_metadata,
        }

    blender = scan(
        ("density", "float", "fog volume", {}), ("velocity", "vec3s", "staggered", {"file_base_resolution": [8, 8, 8]})
    )
    found = find_velocity("b.vdb", blender)
    assert (found.grids, found.staggered, found.units, found.fps) == (("velocity",), True, "mantaflow", 24.0)
    assert found.per_frame == 2.5 / 24 and "assumed" in found.fps_from
    houdini = scan(
        ("density", "float", "fog volume", {}), *[(f"vel.{a}", "float", "unknown", {}) for a in "xyz"], fps=25.0
    )
    found = find_velocity("h.vdb", houdini)
    assert (found.grids, found.units, found.fps, found.per_frame) == (
        ("vel.x", "vel.y", "vel.z"),
        "world",
        25.0,
        1 / 25,
    )
    local = scan(("v", "vec3s", "unknown", {"is_local_space": True}))
    assert find_velocity("l.vdb", local, fps=48).units == "index"
    assert find_velocity("n.vdb", scan(("density", "float", "fog volume", {}))) is None
    with pytest.raises(ValueError, match=r"n.vdb has no velocity grid 'wind' .*it holds 'density' \(float\)"):
        find_velocity("n.vdb", scan(("density", "float", "fog volume", {})), "wind")
    with pytest.raises(ValueError, match="Frames per second must be a positive number"):
        find_velocity("b.vdb", blender, fps=0)


@needs_vdb
def test_a_real_mantaflow_velocity_reads_at_the_density_voxels(tmp_path, subprocess_route):
    """Frame 1 of the cache, twice: its staggered 'velocity' in Mantaflow's units, averaged to the cell
    centres of the density's box and scaled to voxels per frame (2.5 / 24 at the assumed 24 fps)."""
    from mistyle.files import load_density_frames

    path = MANTAFLOW / "fluid_data_0001.vdb"
    (tmp_path / "seq").mkdir()
    for name in ("fluid_data_0001.vdb", "fluid_data_0002.vdb"):
        (tmp_path / "seq" / name).write_bytes(path.read_bytes())
    notes = []
    loaded = load_density_frames(tmp_path / "seq", notes=notes)
    velocity = loaded.velocities[0]
    assert velocity.shape == (28, 9, 11, 3) == loaded.densities[0].shape + (3,)
    assert np.all(np.isfinite(velocity)) and np.abs(velocity).max() > 1.0
    assert "Blender Mantaflow's solver units" in notes[0] and "24 fps (assumed" in notes[0]
    # Independently: the raw faces (index box (63, 115, 9)..) in the density's box (63, 115, 7).., with
    # one zero face beyond it, and the centre of each voxel the mean of its two faces along each axis.
    raw, _, _ = read_vdb(path, grid="velocity")  # (26, 9, 11, 3)
    faces = np.zeros((29, 10, 12, 3), np.float32)
    faces[2:28, 0:9, 0:11] = raw
    centred = np.stack(
        [
            (faces[:28, :9, :11, 0] + faces[:28, :9, 1:12, 0]) / 2,
            (faces[:28, :9, :11, 1] + faces[:28, 1:10, :11, 1]) / 2,
            (faces[:28, :9, :11, 2] + faces[1:29, :9, :11, 2]) / 2,
        ],
        axis=-1,
    )
    np.testing.assert_allclose(velocity, centred * 2.5 / 24, rtol=1e-5, atol=1e-6)

    # A grid read beside the density may be empty (a velocity where nothing moves yet): None, not an error.
    density, (flame, temperature) = vdb.read_vdb_grids(path, also=["flame", "temperature"])
    assert flame is None and temperature.array.shape == density.array.shape == (28, 9, 11)

    # The real sequence: frame 10's velocity was cut, so no frame has one; a name asked for must be there.
    with pytest.raises(ValueError, match=r"fluid_data_0010.vdb has no velocity grid 'velocity'"):
        load_density_frames(MANTAFLOW, velocity_grid="velocity")
