"""Solid textures (mistyle.solid_texture): slices with the style's patches, laid over a density's box."""

import numpy as np
import pytest
import torch

from mistyle.objective.losses import masked_patches, sliced_wasserstein_loss
from mistyle.solid_texture import (
    SolidTextureSettings,
    _random_patches,
    lay_over,
    synthesise_solid_texture,
    texture_in_box,
)

SMALL = dict(side=16, exemplar_side=24, levels=2, patch=3, steps=60, patches=2048, projections=32, pool=64)


def stripes(width: int = 3) -> np.ndarray:
    """Red and blue vertical stripes, 24 x 24."""
    image = np.zeros((24, 24, 3), np.float32)
    red = (np.arange(24) // width) % 2 == 0
    image[:, red, 0] = 1.0
    image[:, ~red, 2] = 1.0
    return image


def test_random_patches_are_patches_of_axis_slices():
    volume = torch.arange(3 * 6**3, dtype=torch.float32).reshape(3, 6, 6, 6)
    patches = _random_patches(volume, 60, 3, torch.Generator().manual_seed(1))
    slices = torch.cat([volume.permute(1, 0, 2, 3), volume.permute(2, 0, 1, 3), volume.permute(3, 0, 1, 2)])
    every = {tuple(row.tolist()) for row in masked_patches(slices, None, 3)}
    assert patches.shape == (60, 27)
    assert all(tuple(row.tolist()) in every for row in patches)


def test_sliced_loss_compares_each_point_with_the_quantile_at_its_rank():
    generator = torch.Generator().manual_seed(0)
    points = torch.randn(200, 5, generator=generator, dtype=torch.float64).requires_grad_(True)
    target = torch.randn(300, 5, generator=generator, dtype=torch.float64) + 1.0
    loss = sliced_wasserstein_loss(points, target, 16, torch.Generator().manual_seed(3))
    loss.backward()
    directions = torch.randn(5, 16, generator=torch.Generator().manual_seed(3)).to(points)
    directions = directions / directions.norm(dim=0, keepdim=True)
    reference_points = points.detach().clone().requires_grad_(True)
    ours = torch.sort(reference_points @ directions, dim=0).values
    theirs = torch.sort(target @ directions, dim=0).values
    quantiles = torch.stack(
        [torch.from_numpy(np.interp(np.linspace(0, 299, 200), np.arange(300), column.numpy())) for column in theirs.T]
    ).T
    reference = ((ours - quantiles) ** 2).mean() * 5
    reference.backward()
    assert float(loss.detach()) == pytest.approx(float(reference.detach()), rel=1e-9)
    assert torch.allclose(points.grad, reference_points.grad, rtol=1e-9, atol=1e-12)


def test_a_solid_texture_takes_the_styles_colours_and_stripes():
    style = stripes()
    texture = synthesise_solid_texture(style, SolidTextureSettings(**SMALL))
    assert texture.shape == (16, 16, 16, 3) and texture.dtype == np.float32
    assert texture.min() >= 0.0 and texture.max() <= 1.0
    # The start is the style's mean (purple); the style has no purple, so neither may most texels.
    red = (texture[..., 0] > 0.7) & (texture[..., 2] < 0.3)
    blue = (texture[..., 2] > 0.7) & (texture[..., 0] < 0.3)
    assert (red | blue).mean() > 0.6 and red.mean() > 0.15 and blue.mean() > 0.15
    again = synthesise_solid_texture(style, SolidTextureSettings(**SMALL))
    np.testing.assert_array_equal(texture, again)


def test_texture_in_box_keeps_texels_square_and_lay_over_fills_only_the_box():
    texture = np.random.default_rng(0).random((8, 8, 8, 3)).astype(np.float32)
    assert texture_in_box(texture, (8, 4, 8)).shape == (8, 4, 8, 3)
    np.testing.assert_allclose(texture_in_box(texture, (8, 8, 8)), texture, atol=1e-6)
    np.testing.assert_allclose(texture_in_box(texture, (8, 4, 8)), texture[:, 2:6], atol=1e-6)
    density = np.zeros((10, 10, 10), np.float32)
    density[2:6, 3:7, 1:9] = 1.0
    albedo = lay_over(texture, density)
    assert albedo.shape == (10, 10, 10, 3)
    assert not albedo[density == 0].any() and albedo[density > 0].any()
    assert not lay_over(texture, np.zeros((4, 4, 4), np.float32)).any()


@pytest.mark.parametrize(
    "settings, message",
    [
        (dict(side=4), "side"),
        (dict(side=16, levels=3, patch=5), "coarsest"),
        (dict(patch=4), "odd"),
        (dict(projections=600), "pool"),
    ],
)
def test_settings_are_checked(settings, message):
    with pytest.raises(ValueError, match=message):
        SolidTextureSettings(**settings)


def test_a_solid_texture_refuses_what_is_not_a_picture():
    with pytest.raises(ValueError, match="RGB picture"):
        synthesise_solid_texture(np.full((8, 8, 3), np.nan, np.float32), SolidTextureSettings(**SMALL))
