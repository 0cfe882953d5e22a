"""Losses and metrics: exact matching, zero where they should be, finite gradients, the warp."""

import numpy as np
import pytest
import torch

from mistyle.objective.losses import (
    gram_loss,
    histogram_loss,
    mean_std_loss,
    temporal_loss,
    tv_loss,
)
from mistyle.objective.masks import pool_mask, render_mask
from mistyle.objective.metrics import (
    colour_histogram_distance,
    multiview_spread,
    sliced_wasserstein,
    style_distance,
    temporal_flicker,
)
from mistyle.tone import tone_map
from mistyle.warp import semi_lagrangian_warp

GEN = torch.Generator().manual_seed(0)


def test_histogram_loss_matches_rank_for_rank_for_equal_sizes():
    values = torch.randn(1, 1, 50, 1, generator=GEN, dtype=torch.float64)
    target = torch.rand(1, 50, 1, generator=GEN, dtype=torch.float64) * 7
    # Equal counts: the k-th smallest value is matched with the k-th smallest target value.
    expected = ((torch.sort(values.flatten()).values - torch.sort(target.flatten()).values) ** 2).mean()
    torch.testing.assert_close(histogram_loss(values, target), expected)


def test_histogram_loss_interpolates_the_style_quantiles_for_other_sizes():
    values = torch.tensor([3.0, 1.0, 2.0]).reshape(1, 1, 3, 1)
    style = torch.tensor([0.0, 1.0, 2.0, 3.0, 4.0]).reshape(1, 5, 1)
    # Quantiles at 0, 1/2, 1 of the style are 0, 2, 4: the values 1, 2, 3 are matched with them.
    loss = histogram_loss(values, style)
    assert float(loss) == pytest.approx(((1 - 0) ** 2 + (2 - 2) ** 2 + (3 - 4) ** 2) / 3)


def test_style_losses_vanish_on_the_style_itself_and_have_finite_gradients():
    style = torch.rand(4, 6, 5, generator=GEN)
    features = style[None].clone().requires_grad_()
    mask = torch.ones(1, 1, 6, 5)
    for loss_fn in (histogram_loss, gram_loss, mean_std_loss):
        assert float(loss_fn(features, style, mask).detach()) == pytest.approx(0.0, abs=1e-10)
    shifted = (style[None] * 2 + 1).requires_grad_()
    for loss_fn in (histogram_loss, gram_loss, mean_std_loss):
        loss = loss_fn(shifted, style, mask)
        assert float(loss.detach()) > 0
        (grad,) = torch.autograd.grad(loss, shifted)
        assert torch.isfinite(grad).all()


def test_histogram_loss_ignores_masked_out_values_and_empty_masks():
    style = torch.rand(2, 4, 4, generator=GEN)
    features = torch.cat([style, torch.full((2, 4, 4), 99.0)], dim=2)[None]  # background is way off
    mask = torch.cat([torch.ones(1, 1, 4, 4), torch.zeros(1, 1, 4, 4)], dim=3)
    assert float(histogram_loss(features, style, mask)) == pytest.approx(0.0, abs=1e-10)
    assert float(histogram_loss(features, style, torch.zeros_like(mask))) == 0.0


def test_tv_is_zero_for_constants_and_positive_otherwise():
    assert float(tv_loss(torch.full((1, 3, 4, 5, 6), 0.3))) == 0.0
    ramp = torch.arange(6.0).expand(1, 1, 4, 5, 6)
    assert float(tv_loss(ramp)) == pytest.approx(1.0)


def test_tvs_written_out_gradient_is_the_formulas():
    """``tv_loss``'s hand-written backward against autograd of the plain formula, and finite differences;
    an axis of one value contributes nothing."""
    volume = torch.rand(2, 3, 5, 1, 7, generator=GEN, dtype=torch.float64, requires_grad=True)
    plain = sum((torch.diff(volume, dim=axis) ** 2).mean() for axis in (2, 4))
    (expected,) = torch.autograd.grad(plain, volume)
    (gradient,) = torch.autograd.grad(tv_loss(volume), volume)
    torch.testing.assert_close(gradient, expected, rtol=1e-12, atol=1e-15)
    assert float(tv_loss(volume).detach()) == pytest.approx(float(plain.detach()), rel=1e-12)
    assert torch.autograd.gradcheck(tv_loss, (volume,))


def test_warp_is_exact_for_integer_translations():
    volume = torch.rand(1, 2, 8, 9, 10, generator=GEN)
    velocity = torch.zeros(1, 3, 8, 9, 10)
    velocity[:, 0], velocity[:, 1], velocity[:, 2] = 2.0, -1.0, 1.0  # (x, y, z) voxels per frame
    warped = semi_lagrangian_warp(volume, velocity)
    # warped(x, y, z) = volume(x - 2, y + 1, z - 1) away from the clamped border
    torch.testing.assert_close(warped[..., 1:, :-1, 2:], volume[..., :-1, 1:, :-2], rtol=0, atol=1e-6)


def test_temporal_loss_is_zero_for_a_correctly_advected_sequence():
    previous = torch.rand(1, 3, 6, 6, 6, generator=GEN, requires_grad=True)
    velocity = torch.rand(1, 3, 6, 6, 6, generator=GEN)
    current = semi_lagrangian_warp(previous, velocity).detach()
    assert float(temporal_loss(current, previous, velocity).detach()) == pytest.approx(0.0, abs=1e-12)
    loss = temporal_loss(current + 0.1, previous, velocity)
    loss.backward()
    assert float(loss.detach()) == pytest.approx(0.01, rel=1e-4) and torch.isfinite(previous.grad).all()


def test_tone_map_is_bounded_monotone_and_smooth_at_zero():
    x = torch.tensor([0.0, 0.01, 1.0, 100.0, 1e6], requires_grad=True)
    y = tone_map(x)
    values = y.detach()
    assert float(values[0]) == 0.0 and torch.all(torch.diff(values) > 0) and float(values[-1]) < 1.0
    y.sum().backward()
    assert torch.isfinite(x.grad).all()


def test_sliced_wasserstein_keeps_the_reference_sets_sorted_projections_and_gives_the_plain_value():
    from mistyle import memo

    rng = np.random.default_rng(1)
    a, b = rng.random((500, 3)), rng.random((800, 3)) ** 2
    directions = np.random.default_rng(0).normal(size=(128, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    levels = (np.arange(800) + 0.5) / 800

    def quantiles(values):  # linear quantiles at `levels`, as numpy takes them
        return np.quantile(values, levels, axis=0, method="hazen")

    plain = np.sqrt(np.mean((quantiles(a @ directions.T) - quantiles(b @ directions.T)) ** 2))
    memo.forget()
    first = sliced_wasserstein(a, b)
    assert memo.kept_count() == 1  # b's sorted projections, kept
    assert sliced_wasserstein(a, b) == first == pytest.approx(plain, rel=1e-9)
    assert sliced_wasserstein(a, b + 0.1) != first  # other points are not taken for the kept ones
    assert memo.kept_count() == 2


def test_a_pool_of_projected_target_directions_gives_the_plain_loss_along_the_directions_drawn():
    from mistyle.objective.losses import _quantiles, project_target, sliced_wasserstein_loss

    generator = torch.Generator().manual_seed(0)
    points, target = torch.rand(300, 5, generator=generator), torch.rand(700, 5, generator=generator) ** 2
    pooled = project_target(target, 16, generator)
    assert pooled.shape == (700, 5) and pooled.sorted.shape == (16, 700)
    theirs = _quantiles(torch.sort(target @ pooled.directions, dim=0).values.T, 300).T
    plain = ((torch.sort(points @ pooled.directions, dim=0).values - theirs) ** 2).mean() * 5
    # Drawing all 16 of the pool, in any order, gives the plain loss along them.
    torch.testing.assert_close(sliced_wasserstein_loss(points, pooled, 16, generator), plain)
    part = sliced_wasserstein_loss(points, pooled, 4, generator)
    assert 0 < float(part) and not torch.isclose(part, plain)
    with pytest.raises(ValueError, match="dimension"):
        sliced_wasserstein_loss(points[:, :3], pooled)


def test_masks_threshold_and_max_pool():
    images = torch.zeros(1, 3, 8, 8)
    images[0, 1, 2, 3] = 0.01
    mask = render_mask(images)
    assert float(mask.sum()) == 1 and float(pool_mask(mask, (4, 4))[0, 0, 1, 1]) == 1.0


def test_style_metrics():
    rng = np.random.default_rng(0)
    a, b = rng.random((500, 3)), rng.random((800, 3))
    assert sliced_wasserstein(a, a) == 0.0
    assert sliced_wasserstein(a, b) < 0.05 < sliced_wasserstein(a, b * 0.3)
    assert colour_histogram_distance(a, a) == 0.0 and colour_histogram_distance(a, a * 0.2) > 0.5
    render = np.zeros((8, 8, 3), np.float32)
    render[2:6, 2:6] = 0.5
    distances = style_distance(render, np.full((4, 4, 3), float(tone_map(torch.tensor(0.5)))))
    assert distances["swd"] == pytest.approx(0.0, abs=1e-6) and distances["hist"] == 0.0
    with pytest.raises(ValueError, match="non-empty"):
        style_distance(np.zeros((4, 4, 3), np.float32), np.ones((4, 4, 3)))
    assert multiview_spread([1.0, 1.0])["relative_std"] == 0.0


def test_temporal_flicker_is_zero_for_advected_frames():
    rng = np.random.default_rng(1)
    first = rng.random((6, 6, 6, 3)).astype(np.float32)
    velocity = np.zeros((6, 6, 6, 3), np.float32)
    velocity[..., 0] = 1.0
    from mistyle.warp import warp_grid as warp

    second = warp(first, velocity)
    assert temporal_flicker(np.stack([first, second]), np.stack([velocity, velocity])) == pytest.approx(0.0, abs=1e-7)
    assert temporal_flicker(np.stack([first, first]), np.stack([velocity, velocity])) > 0.01


def test_style_metric_subsamples_large_images_with_a_small_error(monkeypatch):
    from mistyle.objective import metrics

    rng = np.random.default_rng(3)
    style = rng.random((300, 300, 3)).astype(np.float32) ** 2
    render = rng.random((40, 40, 3)).astype(np.float32)
    exact = metrics.style_distance(render, style)["swd"]
    monkeypatch.setattr(metrics, "MAX_METRIC_POINTS", 8192)
    assert metrics.style_distance(render, style)["swd"] == pytest.approx(exact, rel=0.02)


def run_metric_under_a_memory_limit(render_side: int, style_side: int) -> float:
    import subprocess
    import sys

    code = (
        "import resource, numpy as np\n"
        "resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))\n"
        "from mistyle.objective.metrics import style_distance\n"
        f"style = np.random.default_rng(0).random(({style_side}, {style_side}, 3), dtype=np.float32)\n"
        f"render = np.full(({render_side}, {render_side}, 3), 0.5, np.float32)\n"
        "print(style_distance(render, style)['swd'])\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    return float(result.stdout.strip())


def test_style_metric_of_a_16_megapixel_style_fits_in_a_small_memory_limit():
    """Before the subsampling, every style pixel was projected on 128 directions: 4.8 GiB per megapixel."""
    assert 0.0 < run_metric_under_a_memory_limit(64, 4096) < 1.0


@pytest.mark.slow
def test_style_metric_of_a_4096_render_fits_in_a_small_memory_limit():
    assert 0.0 < run_metric_under_a_memory_limit(4096, 4096) < 1.0
