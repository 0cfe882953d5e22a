from pathlib import Path

import pytest

from mistyle.model.config import (
    ConfigError,
    config_from_dict,
    config_to_dict,
    load_config,
    to_toml,
)

CONFIGS = sorted(str(path) for path in (Path(__file__).resolve().parents[1] / "configs").glob("*.toml"))


@pytest.mark.parametrize("path", CONFIGS)
def test_shipped_configs_load_and_round_trip(path, tmp_path):
    config = load_config(path)
    written = tmp_path / "resolved.toml"
    written.write_text(to_toml(config_to_dict(config)))
    assert config_to_dict(load_config(written)) == config_to_dict(config)
    assert config_to_dict(config_from_dict(config_to_dict(config))) == config_to_dict(config)


def test_paper_config_has_the_papers_settings():
    config = load_config("configs/paper.toml")
    assert (config.render.image_size, config.render.views, config.render.steps, config.optim.batch) == (160, 4, 64, 8)
    assert (config.optim.lr, config.optim.betas, config.optim.lr_decay, config.optim.decay_every_epochs) == (
        2e-4,
        (0.9, 0.999),
        0.8,
        50,
    )
    assert (config.loss.style_weight, config.loss.tv_weight, config.loss.temporal_weight) == (1, 10, 300)


def test_overrides_are_typed():
    config = load_config(
        "configs/tiny.toml",
        ["optim.lr=1e-3", "optim.steps=5", "model.widths=[4, 8, 8]", "run.device=cpu", "optim.decay_every_epochs=3"],
    )
    assert config.optim.lr == 1e-3 and config.optim.steps == 5 and config.model.widths == (4, 8, 8)
    assert config.optim.decay_every_epochs == 3.0 and isinstance(config.optim.decay_every_epochs, float)


@pytest.mark.parametrize(
    "override, message",
    [
        ("optim.learning_rate=1", "unknown key 'learning_rate'"),
        ("nothing.lr=1", "unknown key 'nothing'"),
        ("optim.steps=1.5", "steps must be int"),
        ('optim.steps="ten"', "steps must be int"),
        ("model.widths=[1, 2]", "must have 3 entries"),
        ("optim.lr=-1", "optim.lr must be a finite number > 0"),
        ("optim.lr=inf", "optim.lr must be a finite number > 0"),
        ("optim.betas=[2, 3]", "optim.betas must be two numbers in"),
        ("optim.decay_every_epochs=0", "decay_every_epochs must be a finite number > 0"),
        ("model.widths=[8, -1, 16]", "widths, style_channels, style_hidden must be >= 1"),
        ("model.style_hidden=0", "widths, style_channels, style_hidden must be >= 1"),
        ("model.residual_blocks=-1", "residual_blocks >= 0; got"),
        ("loss.tv_weight=-1", "a negative weight rewards what its term penalises"),
        ("run.threads=-1", "run.threads must be >= 0"),
        ("run.eval_views=0", "run.eval_styles, run.eval_densities and run.eval_views must be >= 1"),
        ("run.device=tpu", "run.device must be one of cpu, cuda"),
        ("model.kernels=3", "kernels must be 1, 2 or 4"),
        ("optim.lr", "--set takes section.key=value"),
    ],
)
def test_bad_overrides_name_the_key(override, message):
    with pytest.raises(ConfigError, match=message):
        load_config("configs/tiny.toml", [override])


def test_the_removed_palette_heads_keys_load_at_their_old_defaults_and_refuse_the_palette_head(tmp_path):
    old = tmp_path / "old.toml"
    old.write_text('[model]\nhead = "direct"\npalette_spread = 1.0\nkernels = 2\n')
    config = load_config(old, ["model.head=direct"])
    assert config.model.kernels == 2 and "head" not in config_to_dict(config)["model"]
    assert config_to_dict(config_from_dict({"model": {"head": "direct", "palette_spread": 1}})) == config_to_dict(
        config_from_dict({})
    )
    for override in ('model.head="palette"', "model.palette_spread=1.5", 'model.head="rgb"'):
        with pytest.raises(ConfigError, match="the palette output head was removed .*20ba671"):
            load_config(old, [override])


def test_bad_files(tmp_path):
    with pytest.raises(ConfigError, match="does not exist"):
        load_config(tmp_path / "missing.toml")
    broken = tmp_path / "broken.toml"
    broken.write_text("[optim\nlr = 1")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(broken)
    unknown = tmp_path / "unknown.toml"
    unknown.write_text("[optim]\nlr = 1e-3\nmomentum = 0.9\n")
    with pytest.raises(ConfigError, match="unknown key 'momentum'"):
        load_config(unknown)


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--optimize", "--optimize-styles", "0"], "must be >= 1, got 300 and 0"),
        (["--optimize", "--optimize-steps", "-3"], "must be >= 1, got -3 and 3"),
        (["--optimize-steps", "5"], "set the direct optimisation: add --optimize"),
    ],
)
def test_the_direct_optimisations_options_are_checked(tmp_path, capsys, arguments, message):
    from mistyle.train.__main__ import main

    assert main(["--config", "configs/tiny.toml", "--out", str(tmp_path / "run"), *arguments]) == 2
    error = capsys.readouterr().err
    assert message in error and "Traceback" not in error
    assert not (tmp_path / "run").exists()


def test_init_from_another_architecture_names_the_mismatch(tmp_path, capsys):
    from mistyle.train.__main__ import main

    bundled = "mistyle/checkpoints/skpn_noise.pt"  # wider than configs/tiny.toml's network
    assert main(["--config", "configs/tiny.toml", "--init", bundled, "--out", str(tmp_path / "run")]) == 2
    error = capsys.readouterr().err
    assert "does not fit this run's [model] config (size mismatch for" in error and "Traceback" not in error
    assert not (tmp_path / "run").exists()
