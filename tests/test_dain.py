"""DAIN: equals IN for a full mask, ignores zero-density voxels, never NaN."""

import torch

from mistyle.model.dain import dain, density_mask, masked_statistics

GEN = torch.Generator().manual_seed(0)


def test_dain_equals_instance_norm_when_the_mask_is_all_ones():
    x = torch.randn(2, 4, 5, 6, 7, generator=GEN)
    gamma, beta = torch.rand(2, 4, generator=GEN), torch.rand(2, 4, generator=GEN)
    ones = torch.ones(2, 1, 5, 6, 7)
    reference = (
        torch.nn.functional.instance_norm(x, eps=1e-5) * gamma[..., None, None, None] + beta[..., None, None, None]
    )
    torch.testing.assert_close(dain(x, ones, gamma, beta), reference, rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(dain(x, None, gamma, beta), reference, rtol=1e-5, atol=1e-5)


def test_dain_ignores_appended_zero_density_voxels():
    x = torch.randn(1, 3, 4, 5, 6, generator=GEN)
    density = torch.rand(1, 1, 4, 5, 6, generator=GEN) + 0.2
    gamma, beta = torch.rand(1, 3, generator=GEN), torch.rand(1, 3, generator=GEN)
    padded_x = torch.cat([x, torch.randn(1, 3, 4, 5, 3, generator=GEN) * 50], dim=4)  # junk features
    padded_density = torch.cat([density, torch.zeros(1, 1, 4, 5, 3)], dim=4)
    stats = masked_statistics(x, density_mask(density))
    padded_stats = masked_statistics(padded_x, density_mask(padded_density))
    for a, b in zip(stats, padded_stats):
        torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-5)
    out = dain(x, density_mask(density), gamma, beta)
    padded_out = dain(padded_x, density_mask(padded_density), gamma, beta)
    torch.testing.assert_close(padded_out[..., :6], out, rtol=1e-5, atol=1e-5)


def test_all_zero_density_gives_no_nan_and_finite_gradients():
    x = torch.randn(1, 2, 3, 3, 3, generator=GEN, requires_grad=True)
    out = dain(x, density_mask(torch.zeros(1, 1, 3, 3, 3)), torch.ones(1, 2), torch.zeros(1, 2))
    assert torch.isfinite(out).all()
    out.sum().backward()
    assert torch.isfinite(x.grad).all()


def test_mask_is_max_pooled_to_the_feature_resolution():
    density = torch.zeros(1, 1, 8, 8, 8)
    density[0, 0, 5, 2, 7] = 1.0
    mask = density_mask(density, (4, 4, 4))
    assert mask.shape == (1, 1, 4, 4, 4) and float(mask[0, 0, 2, 1, 3]) > 0.99 and float(mask.sum()) < 1.01
