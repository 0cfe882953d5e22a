"""The public API checks its arguments as the command line does: one line that names the argument
and what it takes, before any work (no network loaded, nothing path traced)."""

import pkgutil
from pathlib import Path

import numpy as np
import pytest

import mistyle
from mistyle import api
from mistyle.pipeline import PipelineSettings, RenderSettings
from mistyle.stylizer import Stylizer

STYLE = Path(__file__).resolve().parents[1] / "examples" / "style_marble.png"


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if a check lets the call reach the network or the path tracer."""

    def work(*args, **kwargs):
        pytest.fail("the call started work (the network or the path tracer) before refusing its arguments")

    monkeypatch.setattr(api, "_stylizer", work)
    monkeypatch.setattr(api, "path_trace", work)
    monkeypatch.setattr(Stylizer, "__init__", work)


@pytest.fixture
def albedo(blob_density):
    return np.full(blob_density.shape + (3,), 0.5, np.float32)


def refused(error_type, match: str, call) -> str:
    with pytest.raises(error_type, match=match) as raised:
        call()
    message = str(raised.value)
    assert "\n" not in message, f"not one line: {message!r}"
    return message


def test_display_is_the_function_whatever_was_imported_before():
    import mistyle.objective.metrics  # noqa: F401 - imports the tone curve's module, as much of mistyle does

    shadowing = {module.name for module in pkgutil.iter_modules(mistyle.__path__)} & set(mistyle._PUBLIC)
    assert not shadowing, f"submodules named like public functions replace them on import: {sorted(shadowing)}"
    assert mistyle.display is api.display
    shown = mistyle.display(np.ones((2, 2, 3), np.float32))
    assert shown.shape == (2, 2, 3) and 0 < shown.min() <= shown.max() <= 1


def test_everything_in_all_is_importable_from_the_package():
    assert set(mistyle._PUBLIC) == set(api.__all__)
    for name in api.__all__:
        namespace = {}
        exec(f"from mistyle import {name}", namespace)
        assert namespace[name] is getattr(api, name)


def test_display_refuses_nan_and_inf():
    image = np.ones((4, 4, 3), np.float32)
    image[1, 2, 0], image[3, 3, 2] = np.nan, np.inf
    message = refused(ValueError, r"^image holds 2 NaN/inf value\(s\)", lambda: api.display(image))
    assert "np.nan_to_num" in message


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda d, a: api.fit_look(d, STYLE, settings={"steps": 1}), r"^settings must be a LookSettings"),
        (lambda d, a: api.Pipeline("x"), r"^settings must be a PipelineSettings"),
        (lambda d, a: api.render(d, a, res="32"), r"^res must be an integer in \[8, 8192\], got '32' \(str\)"),
        (lambda d, a: api.render(d, a, light=None), r"^light must be a string: constant"),
        (lambda d, a: api.render(d, a, view="0.25"), r"^view must be an orbit position"),
        (lambda d, a: api.stylize(d, STYLE, strength="0.5"), r"^strength must be a number in \[0, 1\]"),
        (lambda d, a: api.stylize(d, STYLE, refine="yes"), r"^refine must be True or False"),
        (lambda d, a: api.stylize(d, None), r"^style_image must be an image's path, an \(H, W, 3\) array, a PIL"),
        (lambda d, a: api.fit_look(d, STYLE, key_frames="0,1"), r"^key_frames must be a list of frame indices"),
        (lambda d, a: api.display("bright"), r"^image must hold real numbers"),
        (lambda d, a: api.load_density(3), r"^path must be a density file's path"),
    ],
    ids=[
        "fit_look-settings",
        "Pipeline-settings",
        "render-res",
        "render-light",
        "render-view",
        "stylize-strength",
        "stylize-refine",
        "stylize-style_image",
        "fit_look-key_frames",
        "display-image",
        "load_density-path",
    ],
)
def test_arguments_of_the_wrong_type_are_named(no_work, blob_density, albedo, call, match):
    refused(TypeError, match, lambda: call(blob_density, albedo))


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda d, a: api.render(d, a, seed=-1), r"^seed must be in \[0, 2147483647\], got -1"),
        (lambda d, a: api.render(d, a, res=4), r"^res must be in \[8, 8192\]"),
        (lambda d, a: api.render(d, a, spp=0), r"^spp must be in \[1, 65536\]"),
        (lambda d, a: api.render(d, a, light="sun"), r"^light 'sun' is not a known light"),
        (lambda d, a: api.stylize(np.zeros((0, 16, 16, 16)), STYLE), r"^density holds no frames"),
        (lambda d, a: api.stylize([], STYLE), r"^density holds no frames"),
        (lambda d, a: api.fit_look(d, STYLE, key_frames=[5]), r"^key_frames must index the density's 1 frame"),
    ],
    ids=[
        "render-seed",
        "render-res",
        "render-spp",
        "render-light",
        "stylize-no-frames",
        "stylize-empty-list",
        "fit_look-key_frames",
    ],
)
def test_values_out_of_range_are_named(no_work, blob_density, albedo, call, match):
    refused(ValueError, match, lambda: call(blob_density, albedo))


@pytest.mark.parametrize(
    "make, error, match",
    [
        (lambda: RenderSettings(turntable=-2), ValueError, r"^turntable must be in \[0, 3600\], got -2"),
        (lambda: RenderSettings(res=4), ValueError, r"^res must be in \[8, 8192\]"),
        (lambda: RenderSettings(light=None), TypeError, r"^light must be a string"),
        (lambda: RenderSettings(bricks=8, coat_ior=1.5), ValueError, r"^bricks needs one medium under a coat"),
        (lambda: PipelineSettings(strength="0.5"), TypeError, r"^strength must be a number"),
        (lambda: PipelineSettings(colour_match="no"), TypeError, r"^colour_match must be True or False"),
        (lambda: PipelineSettings(camera_distance=0.1), ValueError, r"^camera_distance must lie in"),
        (lambda: PipelineSettings(render={"res": 64}), TypeError, r"^render must be a RenderSettings"),
    ],
    ids=[
        "turntable",
        "res",
        "light",
        "bricks-coat",
        "strength",
        "colour_match",
        "camera_distance",
        "render",
    ],
)
def test_settings_dataclasses_check_their_fields(make, error, match):
    refused(error, match, make)


def gpu_available() -> bool:
    import drjit as dr
    import torch

    return dr.has_backend(dr.JitBackend.CUDA) and torch.cuda.is_available()


@pytest.mark.parametrize(
    "call",
    [
        lambda d, a: api.stylize(d, STYLE, device="cuda"),
        lambda d, a: api.fit_look(d, STYLE, device="cuda"),
        lambda d, a: api.render(d, a, device="cuda"),
    ],
    ids=["stylize", "fit_look", "render"],
)
def test_cuda_without_a_gpu_is_one_line_naming_the_way_around(no_work, blob_density, albedo, call):
    from mistyle.backend import BackendError

    if gpu_available():
        pytest.skip("this machine has a GPU")
    refused(BackendError, r'Run with device="cpu"', lambda: call(blob_density, albedo))


def test_the_apis_render_is_denoised_as_the_commands(blob_density, albedo):
    """``mistyle.render`` gives what ``mistyle-render`` shows: the path tracer's image through OIDN by
    default, the raw estimate with ``denoise="none"`` (it once skipped the denoiser)."""
    from mistyle.denoise import denoise

    settings = dict(res=32, spp=4, seed=3)
    raw = mistyle.render(blob_density, albedo, denoise="none", **settings)
    shown = mistyle.render(blob_density, albedo, **settings)
    np.testing.assert_array_equal(shown, denoise(raw))
    assert not np.array_equal(shown, raw)
    refused(ValueError, r"^denoise must be one of", lambda: mistyle.render(blob_density, albedo, denoise="nlm"))


def test_a_pil_image_is_a_style_as_its_array_is(mi, blob_density, tiny_checkpoint_factory, tmp_path):
    """``Pipeline.stylize`` took a PIL image and ``mistyle.stylize`` refused it."""
    from PIL import Image

    checkpoint = tiny_checkpoint_factory(tmp_path / "tiny.pt")
    with Image.open(STYLE) as image:
        picture = image.convert("RGB")
    from_picture = mistyle.stylize(blob_density, picture, checkpoint=checkpoint)
    from_array = mistyle.stylize(blob_density, np.asarray(picture), checkpoint=checkpoint)
    np.testing.assert_array_equal(from_picture, from_array)
