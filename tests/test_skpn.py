"""SKPN shapes (odd and non-cubic), variants, empty density, gradients."""

import pytest
import torch

from mistyle.model.skpn import SKPN, SKPNConfig, parameter_count

GEN = torch.Generator().manual_seed(0)
TINY = dict(widths=(4, 8, 8), style_channels=(3, 4, 5, 6), style_hidden=16)


def style_levels(batch=1):
    return [torch.rand(batch, c, 8 // 2**i, 8 // 2**i, generator=GEN) for i, c in enumerate(TINY["style_channels"])]


@pytest.mark.parametrize("shape", [(9, 10, 11), (8, 16, 8), (5, 7, 3)])
def test_any_grid_size_is_accepted(shape):
    model = SKPN(SKPNConfig(**TINY))
    albedo = model(torch.rand((2, 1) + shape, generator=GEN), style_levels(2)).detach()
    assert albedo.shape == (2, 3) + shape
    assert float(albedo.min()) >= 0 and float(albedo.max()) <= 1


@pytest.mark.parametrize("variant", [dict(kernels=1), dict(kernels=2), dict(kernel_size=3), dict(norm="in"), dict(stylize="adain")])
def test_ablation_variants_run_and_backpropagate(variant):
    model = SKPN(SKPNConfig(**TINY, **variant))
    density = torch.rand(1, 1, 8, 8, 8, generator=GEN)
    levels = [level.requires_grad_() for level in style_levels()]
    model(density, levels).mean().backward()
    assert all(torch.isfinite(p.grad).all() for p in model.parameters() if p.grad is not None)
    assert torch.isfinite(levels[-1].grad).all()


def test_empty_density_gives_no_nan():
    albedo = SKPN(SKPNConfig(**TINY))(torch.zeros(1, 1, 8, 8, 8), style_levels()).detach()
    assert torch.isfinite(albedo).all()


def test_style_changes_the_output():
    model = SKPN(SKPNConfig(**TINY))
    density = torch.rand(1, 1, 8, 8, 8, generator=GEN)
    with torch.no_grad():
        a, b = model(density, style_levels()), model(density, [2 * level + 1 for level in style_levels()])
    assert float((a - b).abs().max()) > 1e-4


def test_parameter_counts_grow_with_width():
    small = parameter_count(SKPN(SKPNConfig(**TINY)))
    assert small < parameter_count(SKPN(SKPNConfig(widths=(16, 32, 64))))


@pytest.mark.parametrize("kernels, sites", [(1, [0]), (2, [0, 3]), (4, [0, 1, 2, 3])])
def test_kernel_sites_and_the_style_level_each_reads(kernels, sites):
    """Site 0 is the bottleneck (deepest style level), sites 1-3 precede the decoder's last three convs."""
    config = SKPNConfig(**TINY, kernels=kernels)
    model = SKPN(config)
    assert model.sites == sites
    widths = {0: config.widths[2], 1: config.widths[2], 2: config.widths[1], 3: config.widths[0]}
    for site in sites:
        predictor = model.predictors[str(site)]
        level = model.style_for_site[site]
        assert level == 3 - site
        assert predictor.channels == widths[site]
        assert predictor.mlp[0].in_features == 2 * config.style_channels[level]  # mean and std of that level
    # Only the levels read by an active site influence the albedo.
    density = torch.rand(1, 1, 8, 8, 8, generator=GEN)
    levels = [level.requires_grad_() for level in style_levels()]
    model(density, levels).sum().backward()
    for index, level in enumerate(levels):
        used = any(model.style_for_site[site] == index for site in sites)
        assert (level.grad is not None and float(level.grad.abs().sum()) > 0) == used


def test_averaged_checkpoints_hold_the_mean_weights_and_refuse_other_architectures(tmp_path):
    from mistyle.model.checkpoint import CHECKPOINT_FORMAT, average_checkpoints, load_checkpoint, save_checkpoint

    def checkpoint(path, widths, step):
        model = SKPN(SKPNConfig(**{**TINY, "widths": widths}))
        save_checkpoint(path, {"format": CHECKPOINT_FORMAT, "step": step, "config": {}, "extractor": "filterbank",
                               "model": model.state_dict(), "optimizer": {}})
        return model.state_dict()

    a = checkpoint(tmp_path / "a.pt", (4, 8, 8), 10)
    b = checkpoint(tmp_path / "b.pt", (4, 8, 8), 20)
    averaged = load_checkpoint(average_checkpoints([tmp_path / "a.pt", tmp_path / "b.pt"], tmp_path / "mean.pt"))
    assert averaged["step"] == 20 and "optimizer" not in averaged and len(averaged["averaged_from"]) == 2
    for key in a:
        torch.testing.assert_close(averaged["model"][key], (a[key].float() + b[key].float()) / 2)
    checkpoint(tmp_path / "wide.pt", (4, 8, 16), 30)
    with pytest.raises(ValueError, match="one run only"):
        average_checkpoints([tmp_path / "a.pt", tmp_path / "wide.pt"], tmp_path / "bad.pt")
