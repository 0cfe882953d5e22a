"""The SKPN's noise site: its fields, a zero start, crops, strength, blending, training only it, looks."""

import numpy as np
import pytest
import torch

from mistyle.model.config import ConfigError
from mistyle.model.noise import noise_fields
from mistyle.model.skpn import NOISE_SITE, SKPN, SKPNConfig, StylizingKernels

GEN = torch.Generator().manual_seed(0)
TINY = dict(widths=(4, 8, 8), style_channels=(3, 4, 5, 6), style_hidden=16)
NOISY = dict(TINY, noise_scales=(0.05, 0.2), noise_per_scale=2)


def style_levels(batch=1, seed=0):
    generator = torch.Generator().manual_seed(seed)
    return [
        torch.rand(batch, c, 8 // 2**i, 8 // 2**i, generator=generator) for i, c in enumerate(TINY["style_channels"])
    ]


def with_noise_weights(model: SKPN, scale: float = 1.0) -> SKPN:
    """``model`` with its noise predictor's last layer set to give non-zero weights."""
    last = model.noise_predictor.mlp[-1]
    with torch.no_grad():
        last.bias.copy_(scale * torch.randn(last.bias.shape, generator=GEN))
        last.weight.copy_(scale * torch.randn(last.weight.shape, generator=GEN))
    return model


def test_fields_are_seeded_normalised_and_smoother_at_larger_scales():
    fields = noise_fields((12, 16, 20), (0.05, 0.25), 2, seed=3)
    assert fields.shape == (4, 12, 16, 20) and fields.dtype == torch.float32
    assert torch.equal(fields, noise_fields((12, 16, 20), (0.05, 0.25), 2, seed=3))
    assert not torch.equal(fields, noise_fields((12, 16, 20), (0.05, 0.25), 2, seed=4))
    flat = fields.flatten(1)
    assert torch.allclose(flat.mean(1), torch.zeros(4), atol=1e-5)
    assert torch.allclose(flat.std(1), torch.ones(4), atol=1e-4)
    roughness = (fields[:, :, :, 1:] - fields[:, :, :, :-1]).abs().mean(dim=(1, 2, 3))
    assert float(roughness[2:].max()) < 0.6 * float(roughness[:2].min())
    fields.zero_()  # the cached fields are not the caller's to change
    assert noise_fields((12, 16, 20), (0.05, 0.25), 2, seed=3).abs().sum() > 0


def test_oriented_fields_stretch_along_their_axes_and_leave_the_isotropic_ones_as_they_were():
    isotropic = noise_fields((24, 24, 24), (0.04,), 2, seed=1)
    fields = noise_fields((24, 24, 24), (0.04,), 2, seed=1, orientations=("isotropic", "upright", "layers"))
    assert fields.shape == (6, 24, 24, 24) and torch.equal(fields[:2], isotropic)

    def roughness(field, axis):  # mean step between neighbours along a grid axis (Z, Y, X)
        return float(field.diff(dim=axis).abs().mean())

    upright, layers = fields[2], fields[4]
    assert roughness(upright, 1) < 0.5 * min(roughness(upright, 0), roughness(upright, 2))  # smooth along up
    assert roughness(layers, 0) < 0.5 * roughness(layers, 1) and roughness(layers, 2) < 0.5 * roughness(layers, 1)
    config = SKPNConfig(**dict(NOISY, noise_orientations=("isotropic", "layers")))
    assert config.noise_channels == 2 * len(NOISY["noise_scales"]) * NOISY["noise_per_scale"]
    assert SKPN(config).noise_fields((8, 8, 8)).shape == (1, config.noise_channels, 8, 8, 8)
    with pytest.raises(ValueError, match="noise orientations must be distinct names"):
        SKPNConfig(**dict(NOISY, noise_orientations=("diagonal",)))


@pytest.mark.parametrize("scales", [(0.0,), (1.5,), (-0.1, 0.2)])
def test_scales_outside_the_box_are_refused(scales):
    with pytest.raises(ValueError, match="noise scales must lie in"):
        SKPNConfig(**dict(TINY, noise_scales=scales))


def test_a_noise_site_added_to_a_trained_network_starts_where_it_was():
    """Loading a network without a noise site into one with it leaves only the site's predictor missing,
    and the site starts at zero: the same albedo."""
    torch.manual_seed(1)
    plain = SKPN(SKPNConfig(**TINY))
    noisy = SKPN(SKPNConfig(**NOISY))
    missing, unexpected = noisy.load_state_dict(plain.state_dict(), strict=False)
    assert unexpected == [] and missing and all(key.startswith("noise_predictor.") for key in missing)
    density = torch.rand(1, 1, 10, 12, 9, generator=GEN)
    with torch.no_grad():
        assert torch.equal(plain(density, style_levels()), noisy(density, style_levels()))
    kernels = noisy.predict_kernels(style_levels())
    assert kernels.sites[NOISE_SITE]["weight"].shape == (1, 3, 4)


def test_the_site_adds_style_weighted_fields_before_the_tanh():
    """Against the same network without the site: the pre-tanh values differ by exactly the predicted weights
    times the fields, which vary where the density does not (a block of constant density)."""
    density = torch.zeros(1, 1, 16, 16, 16)
    density[..., 2:14, 2:14, 2:14] = 1.0
    model = with_noise_weights(SKPN(SKPNConfig(**NOISY)), scale=0.3)
    plain = SKPN(SKPNConfig(**TINY))
    plain.load_state_dict(model.state_dict(), strict=False)
    with torch.no_grad():
        difference = torch.atanh(2 * model(density, style_levels()).double() - 1) - torch.atanh(
            2 * plain(density, style_levels()).double() - 1
        )
        weight = model.predict_kernels(style_levels()).sites[NOISE_SITE]["weight"][0]
        other = model.predict_kernels(style_levels(seed=5)).sites[NOISE_SITE]["weight"][0]
    expected = torch.einsum("oc,cdhw->odhw", weight.double(), model.noise_fields((16, 16, 16))[0].double())
    assert float((difference[0] - expected).abs().max()) < 1e-3
    assert float(expected[:, 5:11, 5:11, 5:11].std()) > 0.1
    assert float((weight - other).abs().max()) > 1e-3  # another style, other weights


def test_inference_on_a_crop_uses_the_whole_grids_fields():
    """``infer`` crops to the occupied box; the noise it sees there is the whole grid's, cut the same way."""
    model = with_noise_weights(SKPN(SKPNConfig(**NOISY)), scale=2.0).eval()
    density = torch.zeros(1, 1, 24, 20, 28)
    density[..., 8:18, 6:14, 10:22] = torch.rand(1, 1, 10, 8, 12, generator=GEN) + 0.5
    with torch.no_grad():
        whole = model(density, style_levels())
        cropped = model.infer(density, style_levels(), precision="fp32")
    occupied = density[0, 0] > 0
    assert float((whole - cropped)[0][:, occupied].abs().max()) < 0.05
    assert float((whole - cropped)[0][:, occupied].abs().mean()) < 0.01


def test_strength_zero_and_blends_carry_the_noise_site():
    model = with_noise_weights(SKPN(SKPNConfig(**NOISY, kernels=4)))
    kernels = model.predict_kernels(style_levels())
    neutral = model.neutral_kernels(kernels, grey=0.5)
    assert float(neutral.sites[NOISE_SITE]["weight"].abs().max()) == 0.0
    other = model.predict_kernels(style_levels(seed=2))
    half = StylizingKernels.blend([(kernels, 1.0), (other, 1.0)])
    expected = 0.5 * (kernels.sites[NOISE_SITE]["weight"] + other.sites[NOISE_SITE]["weight"])
    assert torch.allclose(half.sites[NOISE_SITE]["weight"], expected)
    density = torch.zeros(1, 1, 12, 12, 12)
    density[..., 2:10, 2:10, 2:10] = 1.0
    with torch.no_grad():
        grey = model(density, neutral)[0][:, 4:8, 4:8, 4:8]
    assert float((grey - 0.5).abs().max()) < 1e-3


@pytest.mark.parametrize("gradient", ["map", "fit"])
def test_training_only_the_noise_site_with_the_colour_match_in_the_loop(mi, tmp_path, tiny_smoke, gradient):
    """``optim.tune`` freezes everything else; ``loss.colour_match`` fits the product's match per item, and
    the gradient passes the fitted map or the fit as well (``loss.colour_match_gradient``)."""
    from mistyle.model.config import load_config
    from mistyle.train.trainer import Trainer

    config = load_config(
        "configs/tiny.toml",
        [
            f'data.smoke="{tiny_smoke}"',
            "optim.steps=3",
            "run.eval_every=100",
            "model.noise_scales=[0.1, 0.25]",
            "model.noise_per_scale=1",
            "loss.colour_match=true",
            f'loss.colour_match_gradient="{gradient}"',
            'optim.tune=["noise_predictor"]',
            "optim.lr=1e-2",
        ],
    )
    trainer = Trainer(config, tmp_path / "run", log=lambda *a: None)
    before = {name: value.detach().clone() for name, value in trainer.model.state_dict().items()}
    trainer.run()
    after = trainer.model.state_dict()
    changed = sorted(name for name in before if not torch.equal(before[name], after[name]))
    assert changed and all(name.startswith("noise_predictor.") for name in changed)
    assert "noise_predictor.mlp.4.bias" in changed  # the zero start moved
    bad = load_config("configs/tiny.toml", [f'data.smoke="{tiny_smoke}"', 'optim.tune=["nothing_here"]'])
    with pytest.raises(ValueError, match="names no parameter"):
        Trainer(bad, tmp_path / "bad", log=lambda *a: None)
    with pytest.raises(ConfigError, match="colour_match_gradient must be one of map, fit"):
        load_config("configs/tiny.toml", ['loss.colour_match_gradient="both"'])


def noisy_tiny_checkpoint(path, noise: bool = True):
    """A tiny SKPN checkpoint with a noise site whose weights are not zero (``noise=False``: the same
    network without the site)."""
    from mistyle import __version__
    from mistyle.model.config import config_to_dict, load_config
    from mistyle.model.features import make_extractor

    config = load_config("configs/tiny.toml", ["model.noise_scales=[0.1]", "model.noise_per_scale=2"])
    config.model.style_channels = make_extractor("filterbank").channels
    torch.manual_seed(3)
    model = with_noise_weights(SKPN(config.model))
    state = model.state_dict()
    if not noise:
        config.model.noise_scales = ()
        state = {key: value for key, value in state.items() if not key.startswith("noise_predictor.")}
    record = {"format": 1, "mistyle_version": __version__, "step": 0, "config": config_to_dict(config)}
    torch.save({**record, "extractor": "filterbank", "density_scale": 20.0, "model": state}, path)
    return path


def test_a_look_of_a_noise_site_network_saves_and_loads_and_starts_without_the_noise(mi, tmp_path, blob_density):
    """Look files store the noise site's kernel under its name; the loaded look gives the same albedo. A look
    starts from the network without its noise (its own texture takes that part): the same look as the
    network without the site fits."""
    from mistyle.look import Look, LookSettings, fit_look
    from mistyle.stylizer import Stylizer

    stylizer = Stylizer(noisy_tiny_checkpoint(tmp_path / "noisy.pt"))
    style = np.random.default_rng(0).random((32, 32, 3))
    settings = LookSettings(steps=2, layer_res=24)
    look = fit_look(stylizer, [blob_density], style, settings=settings)
    assert float(look.kernels.sites[NOISE_SITE]["weight"].abs().max()) == 0.0
    look.save(tmp_path / "a.look")
    again = Look.load(tmp_path / "a.look", stylizer=stylizer)
    albedo = look.stylize(blob_density)
    assert np.array_equal(albedo, again.stylize(blob_density))
    plain = fit_look(
        Stylizer(noisy_tiny_checkpoint(tmp_path / "plain.pt", noise=False)), [blob_density], style, settings=settings
    )
    difference = np.abs(albedo - plain.stylize(blob_density))
    # The fit's threaded adjoint sums in varying order; the colour match's piecewise map can carry a voxel
    # across a knot. Nearly all voxels agree to 1e-3.
    assert difference.mean() < 1e-4 and np.mean(difference > 1e-3) < 0.01, (difference.mean(), difference.max())
