"""Denoised final frames: OIDN on real path-traced images, determinism, the pipeline's option, a missing OIDN."""

import numpy as np
import pytest

from mistyle.denoise import denoise, oidn_missing


@pytest.fixture(scope="module")
def scene(mi, blob_density):
    from mistyle.scenes import CameraPath

    albedo = np.empty(blob_density.shape + (3,), np.float32)
    albedo[..., : blob_density.shape[2] // 2, :] = (0.9, 0.3, 0.2)  # two halves along x: an edge to keep
    albedo[..., blob_density.shape[2] // 2 :, :] = (0.2, 0.4, 0.9)
    return blob_density, albedo, [CameraPath(distance=1.7).view(0.0)]


def test_denoising_brings_few_samples_closer_to_many_than_more_samples_do(scene):
    from mistyle.pathtrace import path_trace

    density, albedo, views = scene
    options = dict(res=48, density_scale=20.0, light="constant:1")
    (reference,), _ = path_trace(density, albedo, views, spp=512, seed=7, **options)
    (noisy,), _ = path_trace(density, albedo, views, spp=8, seed=1, **options)
    (more,), _ = path_trace(density, albedo, views, spp=32, seed=2, **options)
    cleaned = denoise(noisy)

    def error(image):
        return float(np.sqrt(np.mean((image - reference) ** 2)))

    assert cleaned.shape == noisy.shape and cleaned.dtype == np.float32 and cleaned.min() >= 0
    assert error(cleaned) < 0.5 * error(noisy)
    assert error(cleaned) < error(more)
    assert np.array_equal(cleaned, denoise(noisy))  # the same input, the same frame (chunks merge)


def test_the_pipeline_denoises_by_default_and_none_keeps_the_path_tracers_image(scene):
    from mistyle.pathtrace import path_trace
    from mistyle.pipeline import Pipeline, PipelineSettings, RenderSettings

    density, albedo, views = scene

    def traced(denoise_mode):
        pipeline = Pipeline(PipelineSettings(render=RenderSettings(res=32, spp=4, denoise=denoise_mode)))
        frames = pipeline.frames(density)
        return pipeline.path_trace(frames, [albedo], views)[0][0], pipeline

    raw, pipeline = traced("none")
    (expected,), _ = path_trace(density, albedo, views, **pipeline.trace_options())
    assert np.array_equal(raw, expected)
    cleaned, _ = traced("oidn")
    assert not np.array_equal(cleaned, raw)
    with pytest.raises(ValueError, match="denoise must be one of"):
        PipelineSettings(render=RenderSettings(denoise="blur"))


def test_a_missing_oidn_names_the_install_and_the_way_around(monkeypatch):
    import sys

    assert oidn_missing() is None
    monkeypatch.setitem(sys.modules, "mitsuba_oidn", None)  # import fails as on a machine without the wheel
    message = oidn_missing()
    assert "pip install mitsuba-oidn" in message and "--denoise none" in message
