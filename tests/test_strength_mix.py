"""Style strength and style mixing: both act on the predicted stylizing kernels (``api.Stylizer``).

These tests look at the network's albedo (``match_colours=False``); the colour match after it is
tested in tests/test_colour_match.py."""

import numpy as np
import pytest
import torch

from mistyle.data.heldout import held_out_styles
from mistyle.files import load_style
from mistyle.model.skpn import SKPN, SKPNConfig, StylizingKernels
from mistyle.style import style_parts
from mistyle.stylizer import LUMA_WEIGHTS, Stylizer, validate_strength


class NetworkOnly:
    """The bundled ``Stylizer`` whose calls leave out the colour match."""

    def __init__(self):
        self.inner = Stylizer()

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def __call__(self, *args, **kwargs):
        return self.inner(*args, match_colours=False, **kwargs)


@pytest.fixture(scope="module")
def stylizer():
    return NetworkOnly()


@pytest.fixture(scope="module")
def two_styles():
    records = held_out_styles()
    return [load_style(records[name]["path"]) for name in ("hokusai_great_wave", "van_gogh_starry_night")]


@pytest.fixture(scope="module")
def plume():
    rng = np.random.default_rng(3)
    axis = np.linspace(-1.0, 1.0, 20)
    z, y, x = np.meshgrid(axis, axis, axis, indexing="ij")
    return (np.clip(1.0 - (x**2 + y**2 + z**2) / 0.8, 0.0, 1.0) * (0.6 + 0.4 * rng.random((20, 20, 20)))).astype(
        np.float32
    )


def inside(density):
    """Voxels two or more voxels from every face, where the neutral kernel is exact."""
    mask = density > 0.05
    mask[:2], mask[-2:], mask[:, :2], mask[:, -2:], mask[:, :, :2], mask[:, :, -2:] = (False,) * 6
    return mask


def test_strength_one_is_the_network_as_trained(stylizer, two_styles, plume):
    model = stylizer.trained.model
    with torch.no_grad():
        direct = model.infer(torch.from_numpy(plume)[None, None], stylizer.style_inputs(two_styles[0]))
    expected = direct[0].permute(1, 2, 3, 0).clamp(0, 1).numpy()
    np.testing.assert_array_equal(stylizer(plume, two_styles[0], strength=1.0), expected)


def test_strength_zero_is_uniform_grey_of_the_styled_brightness(stylizer, two_styles, plume):
    full = stylizer(plume, two_styles[0])
    neutral = stylizer(plume, two_styles[0], strength=0.0)
    voxels = neutral[inside(plume)]
    assert float(np.ptp(voxels)) < 1e-4  # one value in every channel and voxel
    grey = float(np.tensordot(plume / plume.sum(), full, axes=3) @ LUMA_WEIGHTS)
    np.testing.assert_allclose(voxels.mean(), grey, atol=1e-3)  # bfloat16 inference (SKPN.infer): 1.5e-4 here


def test_strength_moves_the_albedo_monotonically(stylizer, two_styles, plume):
    full = stylizer(plume, two_styles[0])
    mask = inside(plume)
    distances = [
        float(np.abs(stylizer(plume, two_styles[0], strength=s) - full)[mask].mean()) for s in (0.0, 0.5, 0.8, 1.0)
    ]
    assert distances[0] > distances[1] > distances[2] > distances[3] == 0.0


def test_mix_weights_are_normalised_and_endpoints_are_the_styles(stylizer, two_styles, plume):
    a, b = two_styles
    only_a = stylizer(plume, a)
    np.testing.assert_array_equal(stylizer(plume, [(a, 1.0), (b, 0.0)]), only_a)
    np.testing.assert_allclose(stylizer(plume, [(a, 7.0), (b, 3.0)]), stylizer(plume, [(a, 0.7), (b, 0.3)]), atol=1e-6)
    only_b = stylizer(plume, b)
    mask = inside(plume)
    assert float(np.abs(only_a - only_b)[mask].mean()) > 0.03  # the two styles differ, so the mix is visible
    to_a = [float(np.abs(stylizer(plume, [(a, 1 - w), (b, w)]) - only_a)[mask].mean()) for w in (0.25, 0.5, 0.75)]
    assert 0.0 < to_a[0] < to_a[1] < to_a[2]


def test_blend_is_the_weighted_sum_of_every_kernel_tensor():
    torch.manual_seed(0)
    model = SKPN(SKPNConfig(widths=(4, 8, 8), style_channels=(3, 3, 3, 3), style_hidden=8))
    levels = [torch.rand(2, 3, 8, 8) for _ in range(4)]
    kernels = model.predict_kernels(levels)
    one = StylizingKernels({s: {k: v[:1] for k, v in site.items()} for s, site in kernels.sites.items()})
    two = StylizingKernels({s: {k: v[1:] for k, v in site.items()} for s, site in kernels.sites.items()})
    mixed = StylizingKernels.blend([(one, 3.0), (two, 1.0)])
    for site in kernels.sites:
        for key in kernels.sites[site]:
            torch.testing.assert_close(
                mixed.sites[site][key], 0.75 * one.sites[site][key] + 0.25 * two.sites[site][key]
            )


def test_neutral_kernels_need_a_kernel_before_the_last_convolution():
    model = SKPN(SKPNConfig(widths=(4, 8, 8), style_channels=(3, 3, 3, 3), style_hidden=8, kernels=1))
    kernels = model.predict_kernels([torch.rand(1, 3, 8, 8) for _ in range(4)])
    with pytest.raises(ValueError, match="kernel before its last convolution"):
        model.neutral_kernels(kernels, 0.5)


@pytest.mark.parametrize("strength", [-0.1, 1.5, float("nan")])
def test_bad_strength_is_refused(strength):
    with pytest.raises(ValueError, match=r"strength must lie in \[0, 1\]"):
        validate_strength(strength)


@pytest.mark.parametrize("weights", [(-1.0, 2.0), (0.0, 0.0)])
def test_bad_mix_weights_are_refused(weights):
    with pytest.raises(ValueError, match="weights must be >= 0 with a positive sum"):
        style_parts([("a.png", weights[0]), ("b.png", weights[1])])
