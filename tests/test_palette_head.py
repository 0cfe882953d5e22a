"""The palette head (``SKPNConfig.head = "palette"``) and the style palette it mixes."""

import pytest
import torch

from mistyle.model.skpn import SKPN, SKPNConfig, StylizingKernels
from mistyle.model.style_code import PALETTE_SIZE, style_palette

GEN = torch.Generator().manual_seed(3)
CHANNELS = (3, 4, 5, 6)


def tiny_model(head: str = "palette") -> SKPN:
    torch.manual_seed(0)
    return SKPN(SKPNConfig(widths=(4, 8, 8), style_channels=CHANNELS, style_hidden=16, style_code="quantiles", head=head))


def extractor(images):
    return [images.mean(1, keepdim=True).expand(-1, c, -1, -1)[..., :: 2**i, :: 2**i] for i, c in enumerate(CHANNELS)]


def test_palette_of_two_colours_finds_both_with_their_shares():
    red, blue = torch.tensor([0.9, 0.1, 0.1]), torch.tensor([0.1, 0.2, 0.8])
    image = blue.view(3, 1, 1).expand(3, 32, 32).clone()
    image[:, :8] = red.view(3, 1)[..., None]  # a quarter of the rows
    palette = style_palette(image[None], size=4)
    assert palette.shape == (1, 4, 4)
    torch.testing.assert_close(palette[0, :, 3].sum(), torch.tensor(1.0))
    used = palette[0, palette[0, :, 3] > 0]
    assert len(used) == 2
    by_share = used[used[:, 3].argsort()]
    torch.testing.assert_close(by_share[:, :3], torch.stack([red, blue]))
    torch.testing.assert_close(by_share[:, 3], torch.tensor([0.25, 0.75]))


def test_palette_is_deterministic_and_covers_a_rare_distinct_hue():
    image = 0.5 + 0.05 * torch.randn(1, 3, 48, 48, generator=GEN)
    image[..., :3, :3] = torch.tensor([0.0, 1.0, 0.0]).view(1, 3, 1, 1)  # 9 green pixels of 2304
    palette = style_palette(image.clamp(0, 1))
    assert palette.shape == (1, PALETTE_SIZE, 4)
    torch.testing.assert_close(palette, style_palette(image.clamp(0, 1)), rtol=0, atol=0)
    distance = (palette[0, :, :3] - torch.tensor([0.0, 1.0, 0.0])).norm(dim=1)
    assert float(distance.min()) < 1e-5


def test_palette_refuses_a_bad_image():
    with pytest.raises(ValueError, match="style images must be"):
        style_palette(torch.rand(3, 8, 8))


def test_albedo_is_a_mix_of_the_palette_mapped_to_albedo():
    """Every voxel's albedo lies in the box of the palette colours after ``s c^gamma``, and a one-colour
    palette gives that colour's albedo everywhere."""
    model = tiny_model()
    styles = torch.rand(2, 3, 32, 32, generator=GEN)
    inputs = model.encode_style(styles, extractor)
    density = torch.rand(2, 1, 8, 8, 8, generator=GEN)
    with torch.no_grad():
        albedo = model(density, inputs)
        mapped = model.palette_log_scale.exp() * inputs.palette[..., :3] ** model.palette_log_gamma.exp()
    low, high = mapped.min(dim=1).values, mapped.max(dim=1).values  # (B, 3)
    assert (albedo >= low[..., None, None, None] - 1e-5).all() and (albedo <= high[..., None, None, None] + 1e-5).all()
    kernels = model.predict_kernels(inputs)
    single = torch.tensor([[[0.6, 0.4, 0.2, 1.0]]]).expand(2, 1, 4)
    with torch.no_grad():
        uniform = model(density, StylizingKernels(kernels.sites, single))
    expected = torch.tensor([0.6, 0.4, 0.2]) ** 2.2  # the initial map: s = 1, gamma = 2.2
    torch.testing.assert_close(uniform, expected.view(1, 3, 1, 1, 1).expand_as(uniform), rtol=1e-4, atol=1e-5)


def test_palette_changes_the_albedo_and_gradients_reach_the_head():
    model = tiny_model()
    inputs = model.encode_style(torch.rand(1, 3, 32, 32, generator=GEN), extractor)
    density = torch.rand(1, 1, 8, 8, 8, generator=GEN)
    albedo = model(density, inputs)
    albedo.mean().backward()
    assert all(p.grad is not None and torch.isfinite(p.grad).all() for p in
               [model.palette_log_gamma, model.palette_log_scale, *model.palette_key.parameters(), *model.decoder[2].parameters()])
    darker = inputs._replace(palette=torch.cat([0.5 * inputs.palette[..., :3], inputs.palette[..., 3:]], dim=-1))
    with torch.no_grad():
        assert float((albedo - model(density, darker)).mean()) > 0.03


def test_blend_takes_the_union_of_palettes_and_neutral_is_uniform_grey():
    model = tiny_model()
    inputs = model.encode_style(torch.rand(2, 3, 32, 32, generator=GEN), extractor)
    kernels = model.predict_kernels(inputs)
    neutral = model.neutral_kernels(kernels, 0.3)
    density = torch.rand(2, 1, 8, 8, 8, generator=GEN)
    with torch.no_grad():
        torch.testing.assert_close(model(density, neutral), torch.full((2, 3, 8, 8, 8), 0.3), rtol=1e-4, atol=1e-5)
    mixed = StylizingKernels.blend([(kernels, 3.0), (neutral, 1.0)])
    assert mixed.palette.shape == (2, PALETTE_SIZE + 1, 4)
    torch.testing.assert_close(mixed.palette[..., 3].sum(dim=1), torch.ones(2))
    torch.testing.assert_close(mixed.palette[:, :PALETTE_SIZE, 3], 0.75 * kernels.palette[..., 3])
    only_style = StylizingKernels.blend([(kernels, 1.0), (neutral, 0.0)])
    with torch.no_grad():
        torch.testing.assert_close(model(density, only_style), model(density, kernels))


def test_inputs_must_match_the_head():
    palette_model, direct_model = tiny_model("palette"), tiny_model("direct")
    styles = torch.rand(1, 3, 32, 32, generator=GEN)
    density = torch.rand(1, 1, 8, 8, 8, generator=GEN)
    with pytest.raises(ValueError, match="head='palette'"):
        palette_model(density, direct_model.encode_style(styles, extractor))
    with pytest.raises(ValueError, match="head='direct'"):
        direct_model(density, palette_model.encode_style(styles, extractor))
    with pytest.raises(ValueError, match="head must be"):
        SKPNConfig(head="rgb")


def test_spread_pushes_mixed_colours_away_from_the_palette_mean():
    """``palette_spread`` sigma: the mixed display colour m becomes c_mean + sigma (m - c_mean), the same weights."""
    model = tiny_model()
    spread = SKPN(SKPNConfig(**{**model.config.__dict__, "palette_spread": 1.5}))
    spread.load_state_dict(model.state_dict())
    inputs = model.encode_style(torch.rand(1, 3, 32, 32, generator=GEN), extractor)
    density = torch.rand(1, 1, 8, 8, 8, generator=GEN)
    with torch.no_grad():
        gamma = float(model.palette_log_gamma.exp())  # scale s starts at 1
        mixed = model(density, inputs) ** (1 / gamma)
        colours, shares = inputs.palette[0, :, :3], inputs.palette[0, :, 3]
        mean = (shares[:, None] * colours).sum(0).view(1, 3, 1, 1, 1)
        expected = (mean + 1.5 * (mixed - mean)).clamp(min=1e-6) ** gamma
        torch.testing.assert_close(spread(density, inputs), expected.clamp(0, 1), rtol=1e-4, atol=1e-5)
    with pytest.raises(ValueError, match="palette_spread must be"):
        SKPNConfig(head="palette", palette_spread=0.0)


def test_export_sets_an_inference_setting_and_halves_the_weights(tmp_path):
    from mistyle.model.checkpoint import (
        CHECKPOINT_FORMAT,
        export_checkpoint,
        load_checkpoint,
        model_from_checkpoint,
        save_checkpoint,
    )
    from mistyle.model.config import TrainConfig, config_to_dict
    from mistyle.train.export import main

    model = tiny_model()
    config = TrainConfig()
    config.model = model.config
    source = save_checkpoint(tmp_path / "run.pt", {"format": CHECKPOINT_FORMAT, "mistyle_version": "test", "step": 7,
                                                   "config": config_to_dict(config), "extractor": "filterbank",
                                                   "model": model.state_dict(), "optimizer": {}})
    exported = export_checkpoint(source, tmp_path / "out.pt", ["model.palette_spread=1.5"], half=True)
    checkpoint = load_checkpoint(exported)
    assert "optimizer" not in checkpoint and checkpoint["config"]["model"]["palette_spread"] == 1.5
    assert all(v.dtype == torch.float16 for v in checkpoint["model"].values() if v.is_floating_point())
    loaded, loaded_config = model_from_checkpoint(checkpoint, exported)
    assert loaded_config.model.palette_spread == 1.5
    torch.testing.assert_close(loaded.decoder[2].weight, model.decoder[2].weight, rtol=1e-3, atol=1e-4)
    with pytest.raises(ValueError, match="weights no longer fit"):
        export_checkpoint(source, tmp_path / "bad.pt", ["model.widths=[2, 4, 4]"])
    with pytest.raises(ValueError, match="palette_spread must be"):
        export_checkpoint(source, tmp_path / "bad.pt", ["model.palette_spread=-1"])
    assert not (tmp_path / "bad.pt").exists()
    with pytest.raises(SystemExit, match="take one source"):
        main(["--half", str(source), str(exported), str(tmp_path / "avg.pt")])
