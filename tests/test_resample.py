"""The working resolution (``mistyle.resample``): large grids are stylized on a resampled copy."""

import json

import numpy as np
import pytest

from mistyle.pipeline import Pipeline, PipelineSettings
from mistyle.render_final import main
from mistyle.resample import WorkingGrid, validate_working_size, working_shape

STYLE = "examples/style_marble.png"


def test_the_working_shape_keeps_the_voxels_cubes_and_leaves_smaller_grids_alone():
    assert working_shape((512, 256, 128), 256) == (256, 128, 64)
    assert working_shape((600, 3, 600), 256) == (256, 1, 256)
    assert working_shape((256, 200, 100), 256) is None  # no side longer than the working size
    assert working_shape((512, 512, 512), 0) is None  # 0: the full grid
    assert WorkingGrid.of((20, 18, 16), 16).shape == (16, 14, 13)


@pytest.mark.parametrize("size, error", [(-1, ValueError), (8, ValueError), (5000, ValueError), (2.5, TypeError)])
def test_bad_working_sizes_are_refused(size, error):
    with pytest.raises(error, match="working_size"):
        validate_working_size(size)
    with pytest.raises(error, match="working_size"):
        PipelineSettings(working_size=size)


def test_the_density_is_box_averaged_keeping_its_optical_depth_and_every_wisp(rng):
    full = np.zeros((32, 24, 16), np.float32)
    full[rng.integers(0, 32, 40), rng.integers(0, 24, 40), rng.integers(0, 16, 40)] = 1.0  # isolated voxels
    grid = WorkingGrid((32, 24, 16), (16, 12, 8))
    work = grid.density(full)
    assert work.shape == (16, 12, 8) and work.dtype == np.float32
    assert np.isclose(work.mean(), full.mean())  # the same optical depth through the box, on average
    # each 2x2x2 block holding medium leaves medium in its working voxel, a single voxel an eighth of it
    blocks = full.reshape(16, 2, 12, 2, 8, 2).sum(axis=(1, 3, 5))
    assert np.array_equal(work > 0, blocks > 0) and np.allclose(work, blocks / 8)


def test_velocities_are_measured_in_working_voxels():
    velocity = np.broadcast_to(np.array([2.0, 4.0, 6.0], np.float32), (32, 24, 16, 3))  # (x, y, z) in voxels
    work = WorkingGrid((32, 24, 16), (16, 12, 4)).velocity(velocity)
    assert work.shape == (16, 12, 4, 3)
    assert np.allclose(work, [0.5, 2.0, 3.0])  # x halves along X (16 -> 4 is a quarter), y and z halve


def test_the_albedo_comes_back_from_the_medium_never_from_empty_working_voxels(blob_density):
    grid = WorkingGrid.of(blob_density.shape, 10)
    work = grid.density(blob_density)
    albedo = np.zeros((*grid.shape, 3), np.float32)
    albedo[work > 0] = [0.8, 0.3, 0.0]
    albedo[work == 0] = [0.0, 0.0, 1.0]  # what empty voxels hold is never rendered, and must not leak
    full = grid.albedo(albedo, work)
    assert full.shape == (*blob_density.shape, 3) and full.dtype == np.float32
    medium = blob_density > 0
    assert np.allclose(full[medium], [0.8, 0.3, 0.0], atol=1e-5)  # the weights' floor: a millionth
    # a uniform albedo stays uniform everywhere; the working copy of a full albedo averages by density
    uniform = np.full((*grid.shape, 3), [0.2, 0.5, 0.7], np.float32)
    assert np.allclose(grid.albedo(uniform, work), [0.2, 0.5, 0.7], atol=1e-6)
    assert np.allclose(grid.working_albedo(full, blob_density)[work > 0], [0.8, 0.3, 0.0], atol=1e-5)


def test_a_grid_longer_than_the_working_size_is_stylized_on_its_copy(mi, blob_density):
    """The pipeline stylizes exactly the box-averaged copy and brings its albedo back; the fast layer's
    images of a full albedo are those of its working copy."""
    pipeline = Pipeline(PipelineSettings(working_size=16, refine_steps=0), log=lambda message: None)
    notes = []
    stylized = pipeline.stylize(blob_density, STYLE, notes=notes)
    grid = WorkingGrid.of(blob_density.shape, 16)
    assert stylized.frames.densities[0].shape == blob_density.shape  # what is path traced: the full grid
    assert stylized.albedos[0].shape == (*blob_density.shape, 3)
    assert stylized.report["working_shape"] == [13, 14, 16]
    assert any("copy of the 20x18x16 grid" in note for note in notes)
    whole = Pipeline(PipelineSettings(working_size=0, refine_steps=0), stylizer=pipeline.stylizer)
    work = grid.density(blob_density)
    assert np.array_equal(stylized.network[0], grid.albedo(whole.stylize(work, STYLE).network[0], work))

    views = pipeline.views()
    images = pipeline.layer_images(stylized.frames, 0, stylized.network[0], views)
    copy = stylized.frames.at_working_size(16)
    expected = pipeline.layer_images(copy, 0, grid.working_albedo(stylized.network[0], blob_density), views)
    assert images[0].shape == (256, 256, 3) and np.array_equal(images[0], expected[0])


def test_a_look_fitted_on_the_working_copy_applies_to_full_frames(mi, blob_density):
    pipeline = Pipeline(PipelineSettings(working_size=16, look_steps=2), log=lambda message: None)
    stylized = pipeline.stylize(blob_density, STYLE)
    look = stylized.look
    assert look.meta["key_frame_shape"] == [13, 14, 16]
    assert np.allclose(look.stylize(blob_density, working_size=16), stylized.albedos[0], atol=1e-6)
    applied = pipeline.look_stylization(blob_density, look)
    assert np.allclose(applied.albedos[0], stylized.albedos[0], atol=1e-6)


def test_a_sequence_carries_its_velocities_to_the_working_copy(blob_density):
    pipeline = Pipeline(PipelineSettings(working_size=16))
    velocity = np.broadcast_to(np.array([1.0, 0.0, 0.0], np.float32), (*blob_density.shape, 3))
    frames = pipeline.frames([blob_density, blob_density], velocities=[velocity, velocity])
    work = frames.at_working_size(16)
    assert work is frames.at_working_size(16) and frames.at_working_size(256) is frames
    assert np.allclose(work.velocities[0], [0.8, 0.0, 0.0])  # 20 -> 16 voxels along X
    assert work.motion.velocities[0] is work.velocities[0]  # resampled once for both
    assert work.phases(1) is not None


def test_the_command_records_the_working_size_and_refuses_a_bad_one(mi, tmp_path, blob_density, capsys):
    from mistyle.files import write_vol

    density = tmp_path / "blob.vol"
    write_vol(density, blob_density)
    out = tmp_path / "out"
    common = ["--density", str(density), "--style", STYLE, "--res", "16", "--spp", "1", "--quiet", "--refine", "0"]
    assert main([*common, "--out", str(out), "--working-size", "16"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["inputs"]["working_size"] == 16 and report["working_shape"] == [13, 14, 16]
    assert np.load(out / "albedo.npy").shape == (*blob_density.shape, 3)
    assert main([*common, "--out", str(tmp_path / "bad"), "--working-size", "8"]) != 0
    assert "--working-size must be 0" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()
