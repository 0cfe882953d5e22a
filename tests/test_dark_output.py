"""A final image that cannot show the medium (black, or NaN) is refused with its actual cause, before the work
when the inputs decide it; in a sequence, a frame that shows no medium is a warning on the console."""

import numpy as np
import pytest

from mistyle.files import write_exr, write_vol
from mistyle.pathtrace import medium_pixels, min_medium_pixels, optical_depth, path_trace
from mistyle.pipeline import Pipeline, PipelineSettings, RenderSettings
from mistyle.render_final import main

STYLE = "examples/style_marble.png"
FAST = ["--res", "16", "--spp", "1", "--refine", "0", "--denoise", "none"]


@pytest.fixture(scope="module")
def pipeline():
    """Renders at 16^2 and 2 spp, with what each logs (the console's status lines) kept in ``lines``."""
    lines: list[str] = []
    settings = PipelineSettings(render=RenderSettings(res=16, spp=2, denoise="none"))
    made = Pipeline(settings, log=lines.append)
    made.lines = lines
    return made


def refused(tmp_path, capsys, density, *options) -> str:
    """Run ``mistyle-render`` on ``density``; assert it stopped with exit code 2 before the network ran and
    left no output; return its error line."""
    path = tmp_path / "density.vol"
    write_vol(path, density)
    out = tmp_path / "out"
    code = main(["--density", str(path), "--style", STYLE, "--out", str(out), *FAST, *options])
    error = capsys.readouterr().err
    assert code == 2, error
    assert "stylized" not in error and not out.exists()  # refused before the work, nothing written
    (line,) = [line for line in error.splitlines() if line.startswith("error: ")]
    return line


@pytest.mark.parametrize(
    "factor, advice",
    [
        (1e-30, "The density's largest value is 1e-30: normalise it (density / density.max())"),
        (1e-40, "below float32's normal range, which the path tracer reads as 0: normalise the density"),
    ],
    ids=["tiny", "denormal"],
)
def test_a_density_too_thin_to_see_is_refused_naming_the_fix(mi, tmp_path, capsys, blob_density, factor, advice):
    import torch

    torch.set_flush_denormal(False)  # a data generator run earlier in this process turns it on (mistyle.data)
    line = refused(tmp_path, capsys, (blob_density * factor).astype(np.float32))
    assert "too thin to see at density scale 20" in line and advice in line


def test_a_density_scale_too_low_names_the_scale_that_shows_the_medium(mi, tmp_path, capsys, blob_density):
    line = refused(tmp_path, capsys, blob_density, "--density-scale", "1e-9")
    wanted = 1e-9 / optical_depth(blob_density, 1e-9)
    assert "too thin to see at density scale 1e-09" in line and f"to {wanted:.3g} or more" in line
    # The scale named shows the medium.
    albedo = np.full(blob_density.shape + (3,), 0.5, np.float32)
    (image,), _ = path_trace(blob_density, albedo, Pipeline().views(), res=16, spp=4, density_scale=wanted)
    assert medium_pixels(image) >= min_medium_pixels(16)


@pytest.mark.parametrize("res", ["16", "64"])
def test_a_camera_too_far_is_refused_naming_the_distance(mi, tmp_path, capsys, blob_density, res):
    line = refused(tmp_path, capsys, blob_density, "--camera-distance", "50", "--res", res)
    assert "the camera is too far: at distance 50 the medium spans" in line and "--camera-distance" in line


def test_max_depth_1_is_refused_as_light_never_reaching_the_medium(mi, tmp_path, capsys, blob_density):
    line = refused(tmp_path, capsys, blob_density, "--max-depth", "1")
    assert "max_depth (--max-depth) 1 renders black" in line and "from a depth of 2" in line
    albedo = np.full(blob_density.shape + (3,), 0.5, np.float32)
    with pytest.raises(ValueError, match="from a depth of 2"):  # the library's path tracer too
        path_trace(blob_density, albedo, Pipeline().views(), res=16, spp=1, max_depth=1)


def test_an_environment_map_with_nan_pixels_is_named_as_the_cause(mi, tmp_path, capsys, blob_density):
    environment = np.ones((16, 32, 3), np.float32)
    environment[3, 4] = environment[5, 6, 1] = environment[7, 7] = np.nan
    write_exr(tmp_path / "sky.exr", environment)
    line = refused(tmp_path, capsys, blob_density, "--light", f"envmap:{tmp_path / 'sky.exr'}")
    assert f"{tmp_path / 'sky.exr'} holds 3 NaN pixels" in line and "np.nan_to_num" in line
    assert "density" not in line


def test_an_albedo_with_nan_is_named_with_its_frame_and_count(pipeline, blob_density):
    albedo = np.full(blob_density.shape + (3,), 0.5, np.float32)
    albedo[8, 9, 10] = np.nan
    with pytest.raises(
        ValueError, match=r"albedo of the frame holds 3 NaN/inf value\(s\) \(first at .* \(8, 9, 10, 0\)"
    ):
        pipeline.path_trace(pipeline.frames(blob_density), [albedo])


def test_a_black_albedo_is_refused_after_the_render(pipeline, blob_density):
    black = np.zeros(blob_density.shape + (3,), np.float32)
    with pytest.raises(
        ValueError, match="The final image shows no medium: .* the albedo is black where there is medium"
    ):
        pipeline.path_trace(pipeline.frames(blob_density), [black])


def test_a_filament_thinner_than_a_pixel_is_named_as_such(pipeline):
    from mistyle.pathtrace import medium_span, medium_width

    filament = np.ones((2, 2, 500), np.float32)  # 500 voxels long, 2 across: a tenth of a pixel at 16^2
    view = pipeline.views()[0]
    assert medium_span(filament, view, 16) > 8 and medium_width(filament, view, 16) < 0.5
    grey = np.full(filament.shape + (3,), 0.5, np.float32)
    with pytest.raises(ValueError, match="pixels long but .* across, thinner than the pixels .* Raise the resolution"):
        pipeline.path_trace(pipeline.frames(filament), [grey])


def test_a_sequence_frame_that_shows_no_medium_is_a_warning_on_the_console(pipeline, blob_density):
    """A simulation may start as a wisp: that frame renders, with its cause logged and noted; a sequence
    that no frame shows is refused."""
    wisp = np.zeros_like(blob_density)
    wisp[6:8, 6:8, 6:8] = 1e-4
    albedo = np.full(blob_density.shape + (3,), 0.5, np.float32)
    pipeline.lines.clear()
    notes: list[str] = []
    images, _ = pipeline.path_trace(pipeline.frames([wisp, blob_density]), [albedo, albedo], notes=notes)
    assert medium_pixels(images[0]) == 0 and medium_pixels(images[1]) >= min_medium_pixels(16)
    (warning,) = [line for line in pipeline.lines if line.startswith("warning: ")]
    assert warning.startswith("warning: frame 0 shows no medium: ") and "too thin to see at density scale" in warning
    assert notes == [warning.removeprefix("warning: ")]
    with pytest.raises(ValueError, match="None of the 2 images can show the medium; frame 0: .* too thin"):
        pipeline.path_trace(pipeline.frames([blob_density * 1e-30] * 2), [albedo, albedo])
    # A chunk of a sequence (--frames) that shows no medium renders: the other chunks may show it.
    chunk_notes: list[str] = []
    pipeline.path_trace(pipeline.frames(wisp), [albedo], first=3, notes=chunk_notes)
    assert chunk_notes[0].startswith("frame 3 shows no medium: ")


def test_a_light_too_dim_is_named_instead_of_the_density(mi, blob_density):
    settings = PipelineSettings(render=RenderSettings(res=16, spp=1, denoise="none", light="point:0,3,0:0.001"))
    dim = Pipeline(settings, stylizer=Pipeline().stylizer)
    albedo = np.full(blob_density.shape + (3,), 0.5, np.float32)
    with pytest.raises(ValueError, match="the point light is too dim to show the medium") as refusal:
        dim.path_trace(dim.frames(blob_density), [albedo])
    assert "density scale" not in str(refusal.value)
