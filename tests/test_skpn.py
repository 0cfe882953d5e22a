"""SKPN shapes (odd and non-cubic), variants, empty density, gradients."""

from pathlib import Path

import pytest
import torch

from mistyle.files import load_density
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


@pytest.mark.parametrize(
    "variant", [dict(kernels=1), dict(kernels=2), dict(kernel_size=3), dict(norm="in"), dict(stylize="adain")]
)
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
        save_checkpoint(
            path,
            {
                "format": CHECKPOINT_FORMAT,
                "step": step,
                "config": {},
                "extractor": "filterbank",
                "model": model.state_dict(),
                "optimizer": {},
            },
        )
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


def _training_checkpoint(path, model_table: dict | None = None):
    """A training checkpoint of a tiny SKPN; ``model_table`` replaces the stored config's [model] table."""
    from mistyle.model.checkpoint import CHECKPOINT_FORMAT, save_checkpoint
    from mistyle.model.config import TrainConfig, config_to_dict

    torch.manual_seed(0)
    model = SKPN(SKPNConfig(**TINY))
    config = TrainConfig()
    config.model = model.config
    table = config_to_dict(config)
    if model_table is not None:
        table["model"] = model_table
    save_checkpoint(
        path,
        {
            "format": CHECKPOINT_FORMAT,
            "mistyle_version": "test",
            "step": 7,
            "config": table,
            "extractor": "filterbank",
            "model": model.state_dict(),
            "optimizer": {},
        },
    )
    return model, table


def test_export_sets_a_setting_and_halves_the_weights(tmp_path):
    from mistyle.model.checkpoint import export_checkpoint, load_checkpoint, model_from_checkpoint
    from mistyle.train.export import main

    source = tmp_path / "run.pt"
    model, _ = _training_checkpoint(source)
    exported = export_checkpoint(source, tmp_path / "out.pt", ["data.style_size=96"], half=True)
    checkpoint = load_checkpoint(exported)
    assert "optimizer" not in checkpoint and checkpoint["config"]["data"]["style_size"] == 96
    assert all(v.dtype == torch.float16 for v in checkpoint["model"].values() if v.is_floating_point())
    loaded, loaded_config = model_from_checkpoint(checkpoint, exported)
    assert loaded_config.data.style_size == 96
    torch.testing.assert_close(loaded.decoder[2].weight, model.decoder[2].weight, rtol=1e-3, atol=1e-4)
    with pytest.raises(ValueError, match="weights no longer fit"):
        export_checkpoint(source, tmp_path / "bad.pt", ["model.widths=[2, 4, 4]"])
    with pytest.raises(ValueError, match="data.style_size must be >= 16"):
        export_checkpoint(source, tmp_path / "bad.pt", ["data.style_size=8"])
    assert not (tmp_path / "bad.pt").exists()
    with pytest.raises(SystemExit, match="take one source"):
        main(["--half", str(source), str(exported), str(tmp_path / "avg.pt")])


def test_checkpoints_from_before_the_palette_heads_removal_load_and_a_palette_network_is_refused(tmp_path):
    """The stored [model] table of a checkpoint written while the palette head existed names ``head`` and
    ``palette_spread``: at their old defaults they load as before; a palette-head network is refused,
    naming the decision record and a commit that still has its code."""
    from mistyle.model.checkpoint import export_checkpoint, load_checkpoint, model_from_checkpoint

    table = {**_training_checkpoint(tmp_path / "plain.pt")[1]["model"], "head": "direct", "palette_spread": 1.0}
    model, _ = _training_checkpoint(tmp_path / "old.pt", table)
    loaded, config = model_from_checkpoint(load_checkpoint(tmp_path / "old.pt"), tmp_path / "old.pt")
    assert not hasattr(config.model, "head")
    for key, value in model.state_dict().items():
        torch.testing.assert_close(loaded.state_dict()[key], value)
    _training_checkpoint(tmp_path / "palette.pt", {**table, "head": "palette", "palette_spread": 1.5})
    with pytest.raises(ValueError, match="palette output head was removed.*palette-head-removed.md.*20ba671"):
        model_from_checkpoint(load_checkpoint(tmp_path / "palette.pt"), tmp_path / "palette.pt")
    with pytest.raises(ValueError, match="model.palette_spread = 1.5: the palette output head was removed"):
        export_checkpoint(tmp_path / "old.pt", tmp_path / "bad.pt", ["model.palette_spread=1.5"])


def test_occupied_window_keeps_the_stride_alignment_and_a_margin():
    from mistyle.model.skpn import OCCUPIED_DENSITY, occupied_window

    density = torch.zeros(1, 1, 40, 24, 32)
    density[0, 0, 21:25, 9, 30] = 1.0
    window = occupied_window(density, margin=2)
    assert window == (slice(16, 27), slice(4, 12), slice(28, 32))  # low corners rounded down to a multiple of 4
    assert occupied_window(density, margin=40) is None  # the whole grid
    assert occupied_window(torch.zeros(1, 1, 8, 8, 8), margin=2) is None  # nothing to crop to
    density[0, 0, 0, 0, 0] = OCCUPIED_DENSITY  # a simulation's trace far from the smoke does not grow the box
    assert occupied_window(density, margin=2) == window
    density[0, 0, 0, 0, 0] = 2 * OCCUPIED_DENSITY
    assert occupied_window(density, margin=2) == (slice(0, 27), slice(0, 12), slice(0, 32))


def test_infer_in_float32_without_crop_is_forward_and_the_fast_path_stays_close():
    model = SKPN(SKPNConfig(**TINY)).eval()
    density = torch.zeros(1, 1, 24, 20, 28)
    density[..., 6:14, 5:12, 9:20] = torch.rand(8, 7, 11, generator=GEN)
    style = style_levels()
    with torch.no_grad():
        plain = model(density, style)
    assert torch.equal(model.infer(density, style, precision="fp32", crop_margin=None), plain)
    occupied = density[0, 0] > 0
    for precision, margin in (("bf16", None), ("fp32", 8), ("bf16", 8)):
        fast = model.infer(density, style, precision=precision, crop_margin=margin)
        assert fast.shape == plain.shape and fast.dtype == torch.float32
        change = (fast - plain)[0].permute(1, 2, 3, 0)[occupied].abs()
        # Random weights: a loose bound; the shipped network's is the next test's.
        assert float(change.mean()) < 0.01 and float(change.max()) < 0.1, (precision, margin)
    # Outside the crop the albedo repeats the crop's faces.
    cropped = model.infer(density, style, precision="fp32", crop_margin=2)
    assert torch.equal(cropped[..., 0, :, :], cropped[..., 3, :, :])
    with pytest.raises(ValueError, match="precision"):
        model.infer(density, style, precision="fp16")


def test_the_shipped_networks_fast_path_changes_its_albedo_by_less_than_8_bit_steps():
    """What users get (``SKPN.infer``: bfloat16, empty space cropped) against the float32 forward pass over
    the whole box, on the bundled smoke and a held-out painting."""
    from mistyle.api import Stylizer
    from mistyle.data.heldout import held_out_styles
    from mistyle.model.skpn import OCCUPIED_DENSITY

    stylizer = Stylizer()
    model = stylizer.trained.model
    density = torch.from_numpy(load_density(Path(__file__).parents[1] / "examples" / "smoke_64.vol"))[None, None]
    kernels = stylizer.kernels(held_out_styles()["hokusai_great_wave"]["path"])
    with torch.no_grad():
        plain = model(density, kernels)
    # Where the medium is above the traces the crop leaves out (OCCUPIED_DENSITY), which take the faces' albedo.
    shown = density[0, 0] > OCCUPIED_DENSITY
    change = (model.infer(density, kernels) - plain)[0].permute(1, 2, 3, 0)[shown].abs()
    assert float(change.mean()) < 1.0 / 255 and float(change.quantile(0.99)) < 2.0 / 255


@pytest.mark.parametrize("norm", ["dain", "in"])
def test_the_folded_head_is_the_plain_head_in_value_and_gradient(norm):
    """``folded_head_logits`` (a look's fit) computes ``head_logits(head_site(...))`` as one convolution:
    the same logits, and the same gradients for the last site's kernel and the last convolution."""
    model = SKPN(SKPNConfig(**TINY, norm=norm))
    density = torch.rand(2, 1, 8, 12, 8, generator=GEN)
    density[0, :, :3] = 0  # an empty slab, so the mask weighs voxels unequally
    levels = style_levels(2)
    with torch.no_grad():
        kernels = model.predict_kernels(levels)
        encoded = model.encode(density)
        body = model.decode_body(encoded, kernels)
    folded_input = model.fold_head_input(body, encoded)
    assert SKPN.folds_head(kernels)

    def logits_and_gradients(compute):
        head = {key: value.detach().clone().requires_grad_() for key, value in kernels.sites[3].items()}
        trial = type(kernels)({**kernels.sites, 3: head})
        model.zero_grad()
        logits = compute(trial)
        (logits * torch.linspace(-1, 1, logits.numel()).view_as(logits)).sum().backward()
        grads = [head[key].grad for key in ("weight", "gamma", "beta")]
        grads += [parameter.grad for parameter in model.decoder[2].parameters()]
        return logits.detach(), [g.clone() for g in grads]

    plain, plain_grads = logits_and_gradients(
        lambda trial: model.head_logits(model.head_site(body, trial, encoded), trial, encoded)
    )
    folded, folded_grads = logits_and_gradients(lambda trial: model.folded_head_logits(folded_input, trial, encoded))
    torch.testing.assert_close(folded, plain, rtol=1e-4, atol=1e-5)
    for folded_grad, plain_grad in zip(folded_grads, plain_grads):
        torch.testing.assert_close(folded_grad, plain_grad, rtol=1e-3, atol=1e-5)
    # In bfloat16 (a look's fit where the hardware computes it): float32 logits, within its 8-bit mantissa.
    half, half_grads = logits_and_gradients(
        lambda trial: model.folded_head_logits(folded_input.in_bfloat16(), trial, encoded)
    )
    assert half.dtype == torch.float32
    scale = float(plain.abs().max())
    torch.testing.assert_close(half, plain, rtol=0, atol=0.02 * scale)
    for half_grad, plain_grad in zip(half_grads, plain_grads):
        torch.testing.assert_close(half_grad, plain_grad, rtol=0, atol=0.06 * float(plain_grad.abs().max()))


def test_a_head_with_a_larger_kernel_is_not_folded():
    model = SKPN(SKPNConfig(**TINY, kernel_size=3))
    with torch.no_grad():
        kernels = model.predict_kernels(style_levels())
    assert not SKPN.folds_head(kernels)


def test_kernels_without_noise_give_the_same_albedo_with_no_noise_fields_at_all(blob_density):
    """``encode(..., noise_site=False)``: a look's kernels weigh the shipped network's noise site by zero,
    so leaving its fields out (made for the whole grid: seconds at 256^3) changes no bit of the albedo."""
    from mistyle.api import Stylizer
    from mistyle.data.heldout import held_out_styles

    stylizer = Stylizer()
    model = stylizer.trained.model
    assert model.config.noise_channels > 0
    kernels = stylizer.kernels(held_out_styles()["hokusai_great_wave"]["path"]).without_noise()
    density = torch.from_numpy(blob_density)[None, None]
    with torch.no_grad():
        with_fields = model.decode(model.encode(density), kernels)
        without = model.decode(model.encode(density, noise_site=False), kernels)
    assert model.encode(density, noise_site=False).noise is None
    assert torch.equal(with_fields, without)
