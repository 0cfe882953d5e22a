"""The quantile style code, the fast DAIN statistics, style augmentation, and the paintings split."""

import numpy as np
import pytest
import torch

from mistyle.model.dain import EPSILON, dain, density_mask, masked_statistics
from mistyle.model.skpn import SKPN, SKPNConfig, StyleInputs
from mistyle.model.style_code import (
    CODE_SIZE,
    COLOUR_BASIS,
    COLOUR_DIRECTIONS,
    PATCH_DIRECTIONS,
    PATCH_QUANTILES,
    PATCH_SCALES,
    QUANTILES,
    style_code,
)
from mistyle.train.dataset import augment_styles, hue_rotation

GEN = torch.Generator().manual_seed(0)
COLOUR_PART = COLOUR_DIRECTIONS * QUANTILES


def test_code_of_a_flat_colour_is_its_projections_and_no_pattern():
    colour = torch.tensor([0.8, 0.3, 0.1])
    code = style_code(colour.view(1, 3, 1, 1).expand(1, 3, 32, 32).contiguous())
    assert code.shape == (1, CODE_SIZE) == (1, COLOUR_PART + len(PATCH_SCALES) * PATCH_DIRECTIONS * PATCH_QUANTILES)
    expected = (colour @ COLOUR_BASIS).repeat_interleave(QUANTILES)
    torch.testing.assert_close(code[0, :COLOUR_PART], expected)
    assert float(code[0, COLOUR_PART:].abs().max()) < 1e-5  # patch directions have zero mean per channel


def test_colour_part_ignores_where_pixels_are_and_the_pattern_part_does_not():
    image = torch.rand(1, 3, 32, 32, generator=GEN)
    shuffled = image.flatten(2)[..., torch.randperm(32 * 32, generator=GEN)].view_as(image)
    a, b = style_code(image), style_code(shuffled)
    torch.testing.assert_close(a[:, :COLOUR_PART], b[:, :COLOUR_PART])
    smooth = torch.nn.functional.avg_pool2d(image, 5, stride=1, padding=2)
    assert float((style_code(smooth) - a)[:, COLOUR_PART:].abs().mean()) > 0.05


def test_held_out_styles_get_clearly_different_codes():
    """Code distances between any two held-out styles far exceed those between two crops of one style."""
    from mistyle.data.heldout import held_out_styles
    from mistyle.files import load_style
    from mistyle.model.features import square_style

    images = [load_style(record["path"]) for record in held_out_styles().values()]
    codes = style_code(torch.stack([square_style(image, 64) for image in images]))
    between = torch.cdist(codes, codes)[np.triu_indices(len(codes), 1)]
    within = []
    for image in images:
        half = image.shape[0] // 2
        crops = torch.stack([square_style(image[: half + half // 2], 64), square_style(image[half // 2 :], 64)])
        pair = style_code(crops)
        within.append(float((pair[0] - pair[1]).norm()))
    assert float(between.min()) > 0.4 * float(between.median())
    assert np.median(within) < 0.5 * float(between.median())


def test_quantile_code_reaches_every_predictor():
    config = SKPNConfig(widths=(4, 8, 8), style_channels=(3, 4, 5, 6), style_hidden=16, style_code="quantiles")
    model = SKPN(config)
    extractor = lambda images: [
        images.mean(1, keepdim=True).expand(-1, c, -1, -1)[..., :: 2**i, :: 2**i]  # noqa: E731
        for i, c in enumerate(config.style_channels)
    ]
    styles = torch.rand(2, 3, 32, 32, generator=GEN)
    inputs = model.encode_style(styles, extractor)
    assert inputs.code.shape == (2, CODE_SIZE)
    assert all(
        p.mlp[0].in_features == 2 * config.style_channels[model.style_for_site[int(s)]] + CODE_SIZE
        for s, p in model.predictors.items()
    )
    density = torch.rand(1, 1, 8, 8, 8, generator=GEN)
    one = StyleInputs([level[:1] for level in inputs.levels], inputs.code[:1])
    other = StyleInputs(one.levels, inputs.code[1:])  # same feature moments, another code
    with torch.no_grad():
        assert float((model(density, one) - model(density, other)).abs().max()) > 1e-4
    with pytest.raises(ValueError, match="encode_style"):
        model(density, one.levels)


def reference_statistics(features, mask):
    """DAIN's masked mean and variance written plainly (the definition in ``model.dain``)."""
    weight = mask.expand(-1, 1, *features.shape[2:]).double()
    x = features.double()
    total = weight.sum(dim=(2, 3, 4), keepdim=True)
    mean = (x * weight).sum(dim=(2, 3, 4), keepdim=True) / total
    return mean, (weight * (x - mean) ** 2).sum(dim=(2, 3, 4), keepdim=True) / total


def test_fast_statistics_match_the_definition_even_for_a_large_mean():
    features = torch.randn(2, 3, 6, 7, 5, generator=GEN)
    features[:, 1] = 1000.0 + 0.1 * features[:, 1]  # a channel whose mean dwarfs its spread
    mask = density_mask(torch.rand(2, 1, 6, 7, 5, generator=GEN) * 0.3)
    mean, variance = masked_statistics(features, mask)
    ref_mean, ref_variance = reference_statistics(features, mask)
    torch.testing.assert_close(mean.double(), ref_mean, rtol=1e-6, atol=1e-4)
    torch.testing.assert_close(variance.double(), ref_variance, rtol=2e-3, atol=1e-6)
    gamma, beta = torch.rand(2, 3, generator=GEN), torch.rand(2, 3, generator=GEN)
    expected = (
        gamma[..., None, None, None] * (features - ref_mean.float()) / torch.sqrt(ref_variance.float() + EPSILON)
        + beta[..., None, None, None]
    )
    torch.testing.assert_close(dain(features, mask, gamma, beta), expected, rtol=1e-3, atol=2e-3)


def test_statistics_stay_float32_under_bfloat16_autocast():
    features = torch.randn(1, 4, 8, 8, 8, generator=GEN)
    mask = density_mask(torch.rand(1, 1, 8, 8, 8, generator=GEN))
    with torch.autocast("cpu", dtype=torch.bfloat16):
        mean, variance = masked_statistics(features.bfloat16(), mask)
    assert mean.dtype == variance.dtype == torch.float32
    ref_mean, ref_variance = reference_statistics(features.bfloat16().float(), mask)
    torch.testing.assert_close(variance.double(), ref_variance, rtol=1e-4, atol=1e-6)


def test_hue_rotation_keeps_grey_and_luminance_and_turns_full_circle():
    luminance = torch.tensor([0.299, 0.587, 0.114])
    rotation = hue_rotation(2.0)
    colours = torch.rand(3, 50, generator=GEN) * 0.3 + 0.35  # inside the gamut after rotation
    torch.testing.assert_close(luminance @ (rotation @ colours), luminance @ colours, rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(rotation @ torch.full((3,), 0.4), torch.full((3,), 0.4), rtol=1e-5, atol=1e-5)
    assert float((rotation @ colours - colours).abs().max()) > 0.02
    torch.testing.assert_close(hue_rotation(2 * np.pi), torch.eye(3), rtol=1e-5, atol=1e-5)


def test_augmentation_off_returns_the_styles_and_on_changes_some():
    styles = torch.rand(6, 3, 16, 16, generator=GEN)
    assert augment_styles(styles, np.random.default_rng(0), 0.0) is styles
    changed = augment_styles(styles, np.random.default_rng(0), 1.0)
    assert changed.shape == styles.shape and float(changed.min()) >= 0 and float(changed.max()) <= 1
    assert all(float((a - b).abs().max()) > 1e-3 for a, b in zip(changed, styles))


def test_the_shipped_network_gives_held_out_styles_different_kernels_and_albedos(blob_density):
    """Four held-out paintings of different palettes: the bundled SKPN predicts clearly different
    stylizing kernels and albedos for each (no style collapses onto another)."""
    from mistyle.api import Stylizer
    from mistyle.data.heldout import held_out_styles
    from mistyle.files import load_style

    stylizer = Stylizer()
    records = held_out_styles()
    names = ["hokusai_great_wave", "munch_the_scream", "van_gogh_starry_night", "kandinsky_composition_vii"]
    model = stylizer.trained.model
    albedos, kernels = [], []
    for name in names:
        inputs = stylizer.style_inputs(load_style(records[name]["path"]))
        with torch.no_grad():
            kernels.append(
                torch.cat(
                    [
                        torch.cat(
                            [
                                value.flatten()
                                for value in predictor(
                                    inputs.levels[model.style_for_site[int(site)]], inputs.code
                                ).values()
                            ]
                        )
                        for site, predictor in model.predictors.items()
                    ]
                )
            )
        albedos.append(stylizer(blob_density, load_style(records[name]["path"]), match_colours=False))
    inside = blob_density > 0.05
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            kernel_change = float((kernels[i] - kernels[j]).norm() / kernels[i].norm())
            albedo_change = float(np.abs(albedos[i] - albedos[j])[inside].mean())
            assert kernel_change > 0.05, (names[i], names[j], kernel_change)
            assert albedo_change > 0.03, (names[i], names[j], albedo_change)
