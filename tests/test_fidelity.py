"""The fidelity metrics and the sliced-Wasserstein objective, against analytic and independent references."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from mistyle.objective.losses import masked_patches, sliced_wasserstein_loss
from mistyle.objective.masks import body_mask
from mistyle.objective.metrics import (
    correlation_length,
    exposure_matched_fidelity,
    hue_coverage,
    image_patches,
    kmeans,
    patch_swd,
    sliced_wasserstein,
    srgb_to_lab,
    style_fidelity,
)
from mistyle.objective.style import SlicedObjective


def two_colour_style(size=32):
    style = np.zeros((size, size, 3), np.float32)
    style[: size // 2] = (0.9, 0.2, 0.1)
    style[size // 2 :] = (0.1, 0.2, 0.9)
    return style


def test_sliced_w1_of_a_translation_is_half_its_length():
    # Projections of a set shifted by t along x move by t*u_x; E|u_x| over unit vectors in 3D is 1/2.
    points = np.random.default_rng(1).uniform(size=(4000, 3))
    shift = np.float64([0.3, 0, 0])
    assert sliced_wasserstein(points, points + shift, projections=4096, order=1) == pytest.approx(0.15, rel=0.03)
    assert sliced_wasserstein(points, points, order=1) == 0.0


def test_lab_of_reference_colours():
    lab = srgb_to_lab(np.array([[1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(lab[0], [100, 0, 0], atol=1e-3)
    np.testing.assert_allclose(lab[1], [0, 0, 0], atol=1e-3)
    np.testing.assert_allclose(lab[2], [53.24, 80.09, 67.20], atol=0.05)  # sRGB red, D65 (Lindbloom)


def test_kmeans_finds_separated_clusters():
    rng = np.random.default_rng(0)
    centres = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    points = np.concatenate([c + rng.normal(0, 0.3, (200, 2)) for c in centres])
    found = kmeans(points, 3)
    assert np.sort(np.linalg.norm(found[:, None] - centres[None], axis=-1).min(axis=0)).max() < 0.2


def test_hue_coverage_counts_shared_hue_mass():
    style = two_colour_style()
    pixels = style.reshape(-1, 3)
    assert hue_coverage(pixels, style) == pytest.approx(1.0)
    assert hue_coverage(pixels[: len(pixels) // 2], style) == pytest.approx(0.5, abs=0.01)  # all red: half the mass
    assert hue_coverage(np.full((100, 3), 0.5), style) <= 0.5


def test_patches_are_only_taken_wholly_inside_the_mask():
    image = np.random.default_rng(0).uniform(size=(20, 20, 3)).astype(np.float32)
    mask = np.zeros((20, 20), bool)
    mask[2:9, 2:9] = True  # 7x7: three by three 5x5 patches fit
    assert image_patches(image, mask, 1).shape == (9, 75)
    assert image_patches(image, None, 1).shape == (16 * 16, 75)
    assert image_patches(image, mask, 2).shape[0] == 0  # a 3x3 inside at half resolution
    torch_patches = masked_patches(
        torch.from_numpy(image).permute(2, 0, 1)[None], torch.from_numpy(mask)[None, None].float(), 5
    )
    np.testing.assert_allclose(torch_patches.numpy(), image_patches(image, mask, 1))
    assert patch_swd([image], [np.ones((20, 20), bool)], image) == 0.0


def linear_from_display(display_values):
    """Invert the tone curve, so a render shows exactly ``display_values``."""
    from mistyle.tone import TONE_EPSILON

    compressed = (np.asarray(display_values, np.float64) + TONE_EPSILON ** (1 / 2.2)) ** 2.2 - TONE_EPSILON
    return (compressed / (1 - compressed)).astype(np.float32)


def test_style_fidelity_of_the_style_itself_and_of_a_mean_colour_fill():
    style = two_colour_style(48)
    perfect = style_fidelity([linear_from_display(style)], style)
    assert perfect["rgb_swd"] < 2e-3 and perfect["patch_swd"] < 2e-3 and perfect["hue_coverage"] > 0.99
    grey = style_fidelity([linear_from_display(np.broadcast_to(style.reshape(-1, 3).mean(0), style.shape))], style)
    assert grey["rgb_swd"] > 0.1 and grey["patch_swd"] > 0.1 and grey["hue_coverage"] <= 0.5
    with pytest.raises(ValueError, match="no render sees the medium"):
        style_fidelity([np.zeros((8, 8, 3), np.float32)], style)


def test_the_matched_exposure_shows_a_dim_render_of_the_style_as_the_style():
    style = two_colour_style(48)
    dim = linear_from_display(style) * 0.2  # the style's own picture, five times too dark
    as_rendered = style_fidelity([dim], style)
    matched, exposure = exposure_matched_fidelity([dim], style)
    assert exposure == pytest.approx(5.0, rel=0.02)
    assert as_rendered["rgb_swd"] > 0.1 and matched["rgb_swd"] < 5e-3 and matched["patch_swd"] < 5e-3
    # A grey of the right brightness stays as far from the style's two colours as it was.
    grey = linear_from_display(np.broadcast_to(style.reshape(-1, 3).mean(0), style.shape))
    assert exposure_matched_fidelity([grey], style)[0]["hue_coverage"] <= 0.5
    with pytest.raises(ValueError, match="no render sees the medium"):
        exposure_matched_fidelity([np.zeros((8, 8, 3), np.float32)], style)


def test_sliced_wasserstein_loss_is_zero_on_equal_sets_and_pulls_points_to_the_target():
    generator = torch.Generator().manual_seed(0)
    target = torch.rand(500, 3, generator=generator)
    assert float(sliced_wasserstein_loss(target, target, generator=generator)) < 1e-10
    points = (target * 0.2).requires_grad_(True)
    optimizer = torch.optim.Adam([points], lr=0.02)
    first = None
    for _ in range(150):
        loss = sliced_wasserstein_loss(points, target, generator=generator)
        first = float(loss.detach()) if first is None else first
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    assert float(loss.detach()) < 0.05 * first


def test_sliced_objective_prefers_the_style_and_ignores_pixels_outside_the_mask():
    style = two_colour_style(32)
    objective = SlicedObjective(patch_scales=(1, 2))
    targets = objective.targets(torch.from_numpy(style).permute(2, 0, 1)[None])
    as_render = lambda image: torch.from_numpy(linear_from_display(image)).permute(2, 0, 1)[None, None]  # noqa: E731
    grey = np.broadcast_to(style.reshape(-1, 3).mean(0), style.shape).copy()
    assert float(objective.loss(as_render(style), targets)) < 0.1 * float(objective.loss(as_render(grey), targets))
    masked = style.copy()
    masked[:, :4] = 0.0  # outside the mask: any colour
    mask = torch.ones(1, 1, 32, 32)
    mask[..., :4] = 0
    assert float(objective.loss(as_render(masked), targets, mask)) < 0.1 * float(
        objective.loss(as_render(grey), targets)
    )


def test_gradient_points_are_the_opponent_channels_differences_inside_the_mask():
    from mistyle.objective.losses import gradient_points

    ramp = torch.linspace(0, 1, 16).repeat(1, 3, 16, 1)  # grey, brighter to the right: d/dx only
    points = gradient_points(ramp, None, 1)
    assert points.shape == (14 * 14, 6)
    assert torch.allclose(points[:, 0], torch.full((14 * 14,), 1 / 15)) and points[:, 1:].abs().max() < 1e-6
    mask = torch.ones(1, 1, 16, 16)
    mask[..., :8] = 0
    assert len(gradient_points(ramp, mask, 1)) == 14 * 6  # centres x = 9..14: whole 3x3 neighbourhoods inside
    assert gradient_points(ramp, None, 2).shape == (6 * 6, 6)
    assert gradient_points(ramp, None, 8).shape == (0, 6)  # 2 pixels a side once downsampled


def test_an_image_too_small_for_a_scale_has_no_patches_at_it():
    from mistyle.objective.losses import scaled_patches
    from mistyle.objective.metrics import patch_swd

    strip = torch.rand(1, 3, 3, 256)  # a style reduced to 3 px high: nothing at scale 4 (it was an error)
    assert scaled_patches(strip, None, 4, 5).shape == (0, 75)
    assert scaled_patches(strip[..., :2, :], None, 4, 5).shape == (0, 75)
    style = np.random.default_rng(0).random((20, 256, 3), dtype=np.float32)
    render = np.random.default_rng(1).random((64, 64, 3), dtype=np.float32)
    assert np.isfinite(patch_swd([render], None, style))  # scale 4: 5 px high, one row of patches


def test_structure_term_tells_the_style_s_orientation_from_another():
    stripes = (np.sin(np.arange(32) / 1.5) * 0.4 + 0.5).astype(np.float32)
    style = np.repeat(np.broadcast_to(stripes[None, :], (32, 32))[..., None], 3, axis=2).copy()  # vertical
    objective = SlicedObjective(rgb_weight=0.0, patch_weight=0.0, structure_weight=1.0, structure_scales=(1,))
    targets = objective.targets(torch.from_numpy(style).permute(2, 0, 1)[None])
    as_render = lambda image: torch.from_numpy(linear_from_display(image)).permute(2, 0, 1)[None, None]  # noqa: E731
    same = objective.loss(as_render(style), targets)
    turned = objective.loss(as_render(style.transpose(1, 0, 2)), targets)  # the same stripes, horizontal
    assert float(same) < 0.05 * float(turned)


def test_body_mask_keeps_pixels_a_white_albedo_makes_bright():
    white = torch.zeros(1, 3, 4, 4)
    white[..., :2] = 5.0  # bright body
    white[..., 2] = 0.01  # dim fringe
    mask = body_mask(white)
    assert mask[..., :2].eq(1).all() and mask[..., 2:].eq(0).all()


def test_refinement_brings_a_path_traced_render_closer_to_the_style(mi, blob_density):
    from mistyle.api import path_trace
    from mistyle.fit import MIN_ALBEDO, RefineSettings, refine_albedo
    from mistyle.scenes import CameraPath

    style = two_colour_style(32)
    start = np.full(blob_density.shape + (3,), 0.3, np.float32)
    settings = RefineSettings(layer_steps=40, path_steps=2, layer_res=24, path_res=16, spp=2, camera_distance=2.0)
    refined, seconds = refine_albedo(blob_density, 20.0, start, style, settings, radiance=8.0)
    assert refined.shape == start.shape and seconds > 0
    assert refined.min() >= MIN_ALBEDO * 0.999 and refined.max() <= 1.0
    views = CameraPath(distance=2.0).turntable(2)

    def scored(albedo):
        images, _ = path_trace(blob_density, albedo, views, res=24, spp=16, density_scale=20.0, light="constant:8")
        return style_fidelity(images, style)

    before, after = scored(start), scored(refined)
    assert after["rgb_swd"] < 0.7 * before["rgb_swd"]
    assert after["hue_coverage"] > before["hue_coverage"] + 0.2


def test_matched_uniform_albedo_reproduces_the_style_mean(mi, blob_density):
    from mistyle.api import path_trace
    from mistyle.objective.metrics import foreground_mask
    from mistyle.response import matched_uniform_albedo
    from mistyle.scenes import CameraPath
    from mistyle.tone import display

    style = np.broadcast_to(np.float32([0.7, 0.45, 0.2]), (16, 16, 3))
    views = CameraPath(distance=2.0).turntable(2)
    colour = matched_uniform_albedo(blob_density, 20.0, 8.0, style, views, res=24, spp=32)
    assert colour[0] > colour[1] > colour[2]
    images, _ = path_trace(
        blob_density,
        np.broadcast_to(colour, blob_density.shape + (3,)).copy(),
        views,
        res=24,
        spp=64,
        density_scale=20.0,
        light="constant:8",
    )
    shown = np.concatenate([display(image)[foreground_mask(image)] for image in images])
    np.testing.assert_allclose(shown.mean(0), style[0, 0], atol=0.04)


def test_the_temporal_anchor_holds_a_refined_frame_near_the_previous_one(mi, blob_density):
    from dataclasses import replace

    from mistyle.fit import RefineSettings, refine_albedo

    style = two_colour_style(32)
    start = np.full(blob_density.shape + (3,), 0.3, np.float32)
    settings = RefineSettings(layer_steps=12, path_steps=0, layer_res=16, patch_weight=0.0, camera_distance=2.0)
    free, _ = refine_albedo(blob_density, 20.0, start, style, settings, radiance=8.0)
    held, _ = refine_albedo(
        blob_density, 20.0, start, style, replace(settings, temporal_weight=1e4), radiance=8.0, anchor=start
    )
    assert np.abs(held - start).mean() < 0.5 * np.abs(free - start).mean()


def test_correlation_length_of_gaussian_smoothed_noise_is_analytic():
    # White noise smoothed by a Gaussian of width s has autocorrelation exp(-r^2 / (4 s^2)): it falls to
    # 1/2 at r = 2 s sqrt(ln 2). The mask (a ball) must not count its outline as structure.
    rng = np.random.default_rng(0)
    shape = (48, 48, 48)
    frequencies = np.meshgrid(*[np.fft.fftfreq(n) for n in shape], indexing="ij")
    squared = sum(f**2 for f in frequencies)
    ball = np.linalg.norm(np.indices(shape) - 23.5, axis=0) < 20
    for width in (1.5, 3.0):
        smoothing = np.exp(-2 * np.pi**2 * width**2 * squared)
        field = np.fft.ifftn(np.fft.fftn(rng.standard_normal(shape)) * smoothing).real
        expected = 2 * width * np.sqrt(np.log(2))
        assert correlation_length(field, np.ones(shape, bool)) == pytest.approx(expected, rel=0.06)
        assert correlation_length(field, ball) == pytest.approx(expected, rel=0.06)
    assert correlation_length(rng.standard_normal(shape), ball) < 1.0  # white noise: uncorrelated at one voxel
    with pytest.raises(ValueError, match="non-empty mask"):
        correlation_length(field, np.zeros(shape, bool))


def test_renders_beyond_one_launch_go_in_passes_of_the_same_estimator(mi, blob_density):
    from mistyle.pathtrace import MAX_PASS_SAMPLES, path_trace, sample_passes
    from mistyle.scenes import CameraPath

    # The sizes that crashed Mitsuba (a sample count no pass split divides; a segfault past 2^31 paths).
    for res, spp in ((2048, 1025), (4096, 300), (8192, 65536), (256, 64)):
        passes = sample_passes(res, spp)
        assert sum(passes) == spp and max(passes) * res * res <= max(MAX_PASS_SAMPLES, res * res)
        assert max(passes) - min(passes) <= 1
    assert sample_passes(256, 64) == [64]  # the default render is one launch, as before
    albedo = np.full(blob_density.shape + (3,), 0.6, np.float32)
    views = [CameraPath(distance=2.0).view(0.1)]
    options = {"res": 24, "spp": 32, "density_scale": 20.0, "light": "constant:8"}
    whole, _ = path_trace(blob_density, albedo, views, **options)
    split, _ = path_trace(blob_density, albedo, views, max_pass_samples=24 * 24 * 5, **options)  # 7 passes
    reference, _ = path_trace(blob_density, albedo, views, **{**options, "spp": 512})
    assert not np.array_equal(whole[0], split[0])  # other samples...
    error = [float(np.abs(image[0] - reference[0]).mean()) for image in (whole, split)]
    assert error[1] < 1.5 * error[0]  # ...of the same estimator
    np.testing.assert_allclose(split[0].mean(), reference[0].mean(), rtol=0.05)
