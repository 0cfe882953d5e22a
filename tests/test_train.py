"""End-to-end training on the tiny config: the real CLI, the real layer, in subprocesses."""

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

REPO = Path(__file__).resolve().parents[1]
TINY = str(REPO / "configs" / "tiny.toml")


def command(out, smoke, *extra, launcher=(sys.executable, "-m")):
    return [*launcher, "mistyle.train", "--config", TINY, "--out", str(out), "--set", f'data.smoke="{smoke}"', *extra]


def run(out, smoke, *extra, check=True):
    result = subprocess.run(command(out, smoke, *extra), capture_output=True, text=True, cwd=REPO, timeout=600)
    if check and result.returncode != 0:
        raise AssertionError(f"exit {result.returncode}\n{result.stderr[-3000:]}")
    return result


def records(out):
    return [json.loads(line) for line in (Path(out) / "metrics.jsonl").read_text().splitlines()]


def test_tiny_config_trains_and_its_loss_drops(tmp_path, tiny_smoke):
    out = tmp_path / "run"
    result = run(out, tiny_smoke, "--set", "optim.steps=60", "--set", "run.eval_every=30")
    assert "feature extractor: filterbank" in result.stdout + result.stderr
    rows = records(out)
    steps = [r for r in rows if "loss" in r]
    assert [r["step"] for r in steps] == list(range(1, 61))
    for key in ("step", "loss", "loss_hist", "loss_tv", "loss_temp", "seconds"):
        assert all(key in r for r in steps), key
    losses = np.array([r["loss"] for r in steps])
    assert losses[-20:].mean() < 0.7 * losses[:5].mean()
    evals = [r for r in rows if "val_swd" in r]
    assert [r["step"] for r in evals] == [0, 30, 60]
    assert evals[-1]["val_swd"] < evals[0]["val_swd"]
    assert sorted(p.name for p in (out / "previews").iterdir()) == [
        "step_000000.png",
        "step_000030.png",
        "step_000060.png",
    ]
    assert list((out / "tb").glob("events.out.tfevents.*"))
    checkpoint = torch.load(out / "final.pt", weights_only=True)
    assert checkpoint["step"] == 60 and checkpoint["mistyle_version"]
    assert {"model", "optimizer", "scheduler", "rng", "config", "extractor"} <= checkpoint.keys()
    assert checkpoint["config"]["optim"]["steps"] == 60
    assert not [p for p in out.rglob("*.tmp*")]

    # The direct-optimisation baseline against this network, and the inference export.
    baseline = run(
        tmp_path / "baseline",
        tiny_smoke,
        "--optimize",
        "--checkpoint",
        str(out / "final.pt"),
        "--optimize-steps",
        "3",
        "--optimize-styles",
        "1",
    )
    row = json.loads(baseline.stdout.splitlines()[0])
    assert {"swd_network", "network_seconds", "swd_optimized", "optimize_seconds", "swd_grey"} <= row.keys()
    assert (tmp_path / "baseline" / "baseline.json").is_file()
    from mistyle.model.checkpoint import export_checkpoint, load_model

    exported = export_checkpoint(out / "final.pt", tmp_path / "inference.pt")
    assert "optimizer" not in torch.load(exported, weights_only=True)
    assert exported.stat().st_size < (out / "final.pt").stat().st_size
    load_model(exported)


def test_the_style_fidelity_configuration_trains(tmp_path, tiny_smoke):
    """configs/cpu_sliced.toml's choices: sliced objective on the body, quantile code, bf16, frame t only."""
    out = tmp_path / "run"
    run(
        out,
        tiny_smoke,
        "--set",
        "optim.steps=30",
        "--set",
        "run.eval_every=30",
        "--set",
        'loss.objective="sliced"',
        "--set",
        'loss.mask="body"',
        "--set",
        'model.style_code="quantiles"',
        "--set",
        'run.precision="bf16"',
        "--set",
        'loss.temporal_gradient="current"',
        "--set",
        "data.hue_augment=0.5",
        "--set",
        "run.keep_checkpoints=true",
    )
    rows = records(out)
    steps = [r for r in rows if "loss_hist" in r]
    assert len(steps) == 30 and all(np.isfinite(r["loss_hist"]) for r in steps)
    evals = [r["val_swd"] for r in rows if "val_swd" in r]  # held-out styles and densities, steps 0 and 30
    assert len(evals) == 2 and evals[1] < evals[0]
    assert torch.load(out / "final.pt", weights_only=True)["config"]["loss"]["objective"] == "sliced"
    assert {"val_rgb_swd", "val_patch_swd", "val_hue_coverage"} <= rows[-1].keys()
    assert all(np.isfinite(r["grad_norm"]) for r in steps)
    assert (out / "best.pt").is_file()  # the better of the two evaluations
    assert sorted(p.name for p in (out / "steps").glob("*.pt")) == [
        "step_000010.pt",
        "step_000020.pt",
        "step_000030.pt",
    ]
    assert "optimizer" not in torch.load(out / "steps" / "step_000030.pt", weights_only=True)
    # --init: a new run from those weights starts where the first one's best evaluation was.
    best = min(r["val_rgb_swd"] for r in rows if "val_rgb_swd" in r)
    again = tmp_path / "again"
    run(
        again,
        tiny_smoke,
        "--init",
        str(out / "best.pt"),
        "--set",
        "optim.steps=1",
        "--set",
        'loss.objective="sliced"',
        "--set",
        'loss.mask="body"',
        "--set",
        'model.style_code="quantiles"',
        "--set",
        "optim.clip_grad=1.0",
    )
    assert records(again)[0]["step"] == 0 and abs(records(again)[0]["val_rgb_swd"] - best) < 1e-4
    clash = run(tmp_path / "clash", tiny_smoke, "--init", str(out / "best.pt"), "--resume", check=False)
    assert clash.returncode == 2 and "give one of them" in clash.stderr
    # --init from a palette-head network (that head was removed): refused, naming a commit that has it.
    palette = torch.load(out / "best.pt", weights_only=True)
    palette["config"]["model"]["head"] = "palette"
    torch.save(palette, tmp_path / "palette.pt")
    refused = run(tmp_path / "refused", tiny_smoke, "--init", str(tmp_path / "palette.pt"), check=False)
    assert refused.returncode == 2 and "the palette output head was removed" in refused.stderr


def _kill_after(out, smoke, step, sig, *extra):
    """Start a run, wait for its progress line of ``step``, send ``sig``; returns the process result."""
    process = subprocess.Popen(
        command(out, smoke, *extra), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO
    )
    for line in process.stderr:
        if line.startswith(f"step {step}/"):
            process.send_signal(sig)
            break
    stderr = process.stderr.read()
    process.wait(timeout=120)
    return process.returncode, stderr


def test_resume_after_a_kill_matches_an_uninterrupted_run(tmp_path, tiny_smoke):
    settings = ("--set", "optim.steps=12", "--set", "run.checkpoint_every=4", "--set", "run.eval_every=100")
    run(tmp_path / "straight", tiny_smoke, *settings)
    killed = tmp_path / "killed"
    code, _ = _kill_after(killed, tiny_smoke, 6, signal.SIGKILL, *settings)
    assert code == -signal.SIGKILL
    assert torch.load(killed / "last.pt", weights_only=True)["step"] in (4, 8)
    fresh = run(killed, tiny_smoke, *settings, check=False)  # without --resume an existing run is not overwritten
    assert fresh.returncode == 2 and "pass --resume" in fresh.stderr
    run(killed, tiny_smoke, "--resume", *settings)
    straight = [r["loss"] for r in records(tmp_path / "straight") if "loss" in r]
    resumed = [r["loss"] for r in records(killed) if "loss" in r]
    assert [r["step"] for r in records(killed) if "loss" in r] == list(range(1, 13))
    # Two uninterrupted runs already differ by ~1e-6 after a step (the layer's adjoint scatters with
    # atomics, so sums are reordered between runs) and training amplifies it to ~1e-4 by step 12.
    np.testing.assert_allclose(resumed, straight, rtol=1e-3)


def test_ctrl_c_saves_a_checkpoint_and_exits_cleanly(tmp_path, tiny_smoke):
    out = tmp_path / "run"
    code, stderr = _kill_after(out, tiny_smoke, 3, signal.SIGINT, "--set", "optim.steps=200")
    assert code == 130, stderr
    assert "continue with --resume" in stderr and "Traceback" not in stderr
    saved = torch.load(out / "last.pt", weights_only=True)["step"]
    assert 3 <= saved < 200
    assert records(out)[-1]["step"] == saved


@pytest.mark.parametrize(
    "extra, message",
    [
        (("--set", "optim.nonsense=1"), "unknown key 'nonsense'"),
        (("--set", 'optim.batch="two"'), "batch must be int"),
        (("--set", 'data.styles="/nonexistent/styles"'), "does not exist"),
        (("--set", 'loss.objective="pixels"'), "loss.objective must be one of features, sliced"),
        (("--set", 'run.precision="fp16"'), "run.precision must be one of fp32, bf16"),
        (("--set", 'model.style_code="vgg"'), "style_code must be moments or quantiles"),
        (("--set", "optim.clip_grad=-1.0"), "optim.clip_grad must be >= 0"),
    ],
)
def test_bad_configs_fail_before_any_work(tmp_path, tiny_smoke, extra, message):
    result = run(tmp_path / "run", tiny_smoke, *extra, check=False)
    assert result.returncode == 2 and message in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "run" / "metrics.jsonl").exists()


def test_missing_or_empty_dataset_is_a_clear_error(tmp_path, tiny_smoke):
    missing = subprocess.run(
        command(tmp_path / "run", tmp_path / "nowhere", "--set", 'data.make=""'),
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert (
        missing.returncode == 2
        and "No smoke dataset" in missing.stderr
        and "python -m mistyle.data smoke" in missing.stderr
    )
    empty = tmp_path / "empty"
    shutil.copytree(tiny_smoke, empty)
    manifest = json.loads((empty / "manifest.json").read_text())
    manifest["pairs"] = []
    (empty / "manifest.json").write_text(json.dumps(manifest))
    result = run(tmp_path / "run2", empty, check=False)
    assert result.returncode == 2 and "no frame pairs" in result.stderr
    gone = tmp_path / "gone"
    shutil.copytree(tiny_smoke, gone)
    next(gone.rglob("frame*.npz")).unlink()
    result = run(tmp_path / "run3", gone, check=False)
    assert result.returncode == 2 and "missing" in result.stderr


def test_two_process_ddp_on_cpu(tmp_path, tiny_smoke):
    out = tmp_path / "ddp"
    with socket.socket() as probe:  # a free port, so parallel CI jobs do not collide
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    launcher = (
        sys.executable,
        "-m",
        "torch.distributed.run",
        "--nproc_per_node",
        "2",
        "--master_port",
        str(port),
        "-m",
    )
    result = subprocess.run(
        command(out, tiny_smoke, "--set", "optim.steps=6", "--set", "run.eval_every=100", launcher=launcher),
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=600,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert result.returncode == 0, result.stdout[-1000:] + result.stderr[-3000:]
    checkpoint = torch.load(out / "final.pt", weights_only=True)
    assert checkpoint["world_size"] == 2 and len(checkpoint["rng"]) == 2 and checkpoint["step"] == 6
    assert [r["step"] for r in records(out) if "loss" in r] == list(range(1, 7))


def test_training_reads_ls_from_the_dataset_cache(mi, tmp_path, tiny_smoke, monkeypatch):
    import mistyle.integrators.inscatter as inscatter
    from mistyle.model.config import load_config
    from mistyle.train.trainer import Trainer

    def recompute(*args, **kwargs):
        raise AssertionError("Ls was recomputed during training")

    monkeypatch.setattr(inscatter, "inscattered_radiance", recompute)
    config = load_config(TINY, [f'data.smoke="{tiny_smoke}"', "optim.steps=2", "run.eval_every=1"])
    Trainer(config, tmp_path / "run", log=lambda *a: None).run()
    assert [r["step"] for r in records(tmp_path / "run") if "val_swd" in r] == [0, 1, 2]


@pytest.mark.parametrize("kind", ["filterbank", "vgg16-random", "vgg16"])
def test_a_checkpoint_of_every_extractor_kind_stylizes_through_the_public_api(tmp_path, tiny_smoke, kind, blob_density):
    import mistyle
    from mistyle.model.features import random_vgg16

    weights = tmp_path / "vgg16.pth"
    torch.save({f"features.{k}": v for k, v in random_vgg16(7).features.state_dict().items()}, weights)
    out = tmp_path / kind
    extra = ["--vgg-weights", str(weights)] if kind == "vgg16" else []
    run(
        out,
        tiny_smoke,
        "--set",
        "optim.steps=2",
        "--set",
        f'run.extractor="{kind}"',
        "--set",
        "run.eval_every=100",
        *extra,
    )
    style = np.random.default_rng(0).random((32, 32, 3)).astype(np.float32)
    albedo = mistyle.stylize(blob_density, style, checkpoint=out / "final.pt", vgg_weights=weights if extra else None)
    assert albedo.shape == blob_density.shape + (3,) and np.isfinite(albedo).all()


# ---------------------------------------------------------------------------- recipes
def test_a_recipe_runs_its_stages_chains_their_weights_and_stores_itself(tmp_path, tiny_smoke):
    from mistyle.model.checkpoint import load_checkpoint
    from mistyle.train.recipes import RECIPES

    out = tmp_path / "recipe"
    smoke = f'data.smoke="{tiny_smoke}"'
    argv = [sys.executable, "-m", "mistyle.train", "--recipe", "tiny", "--out", str(out), "--set", smoke, "--quiet"]
    result = subprocess.run(argv, capture_output=True, text=True, cwd=REPO, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    record = json.loads((out / "recipe.json").read_text())
    assert [stage["stage"] for stage in record["stages"]] == ["first", "second"]
    assert record["stages"][1]["reason"] == "step 3"  # select="step:3"
    first, second = load_checkpoint(out / "1_first" / "chosen.pt"), load_checkpoint(out / "2_second" / "chosen.pt")
    assert first["recipe"]["name"] == "tiny" and second["recipe"]["stage"] == "second"
    assert second["recipe"]["recipe"] == RECIPES["tiny"].as_dict()
    assert second["step"] == 3  # the second stage started from the first's weights, as a new run
    started = torch.load(out / "2_second" / "steps" / "step_000003.pt", weights_only=True)
    assert all(torch.equal(started["model"][k], second["model"][k]) for k in second["model"])
    # Run again: finished stages are kept, nothing is trained.
    again = subprocess.run(argv, capture_output=True, text=True, cwd=REPO, timeout=600)
    assert again.returncode == 0 and "stage 1/2" not in again.stderr
    assert json.loads((out / "recipe.json").read_text())["stages"][0]["reason"] == "kept from an earlier run"


def test_recipes_name_package_configs_and_refuse_unknown_names(tmp_path):
    import mistyle
    from mistyle.train.recipes import CONFIG_DIR, RECIPES, Stage, recipe

    assert Path(mistyle.__file__).resolve().parent in CONFIG_DIR.resolve().parents
    for chosen in RECIPES.values():
        assert all((CONFIG_DIR / stage.config).is_file() for stage in chosen.stages), chosen.name
    import hashlib

    from mistyle.train.recipes import product_path, restore_from_history

    for name in ("skpn_cpu", "skpn_noise"):  # each names exactly one file
        made = RECIPES[name]
        assert hashlib.sha256(product_path(name).read_bytes()).hexdigest() == made.product_sha256
    # skpn_cpu.pt is not in the working tree (only recipes start from it): it comes from the history.
    made = RECIPES["skpn_cpu"]
    restored = tmp_path / "restored.pt"
    restore_from_history(REPO, made.product_commit, made.product, restored)
    assert hashlib.sha256(restored.read_bytes()).hexdigest() == made.product_sha256
    with pytest.raises(ValueError, match="could not be read from commit"):
        restore_from_history(REPO, made.product_commit, "mistyle/checkpoints/none.pt", tmp_path / "none.pt")
    from mistyle.stylizer import DEFAULT_CHECKPOINT

    assert DEFAULT_CHECKPOINT.resolve() == (REPO / RECIPES["skpn_noise"].product).resolve()
    shipped = RECIPES["skpn_cpu"]
    with pytest.raises(ValueError, match="Unknown recipe"):
        recipe("nope")
    with pytest.raises(ValueError, match="select must be one of"):
        Stage("x", "tiny.toml", select="best")
    with pytest.raises(ValueError, match="init must be"):
        Stage("x", "tiny.toml", init="somewhere.pt")
    assert product_path("skpn_cpu") == (REPO / shipped.product).resolve()  # what "recipe:skpn_cpu" starts from
    with pytest.raises(ValueError, match="ships no checkpoint"):
        product_path("tiny")


def test_validation_selection_scores_kept_checkpoints_and_picks_the_lowest(mi, tmp_path, tiny_smoke, blob_density):
    from mistyle.train import recipes

    run(
        tmp_path / "run",
        tiny_smoke,
        "--set",
        "optim.steps=4",
        "--set",
        "run.checkpoint_every=2",
        "--set",
        "run.keep_checkpoints=true",
        "--set",
        "run.eval_every=100",
    )
    kept = recipes.kept_checkpoints(tmp_path / "run")
    assert [p.name for p in kept] == ["step_000002.pt", "step_000004.pt"]
    chosen = recipes.select(
        recipes.Stage("s", "tiny.toml", select="validation"),
        tmp_path / "run",
        styles=1,
        res=16,
        spp=1,
        densities=[blob_density],
    )
    assert set(chosen.scores) == {str(p) for p in kept} and all(np.isfinite(list(chosen.scores.values())))
    assert chosen.chosen == min(chosen.scores, key=chosen.scores.get)
    against_noise = recipes.select(
        recipes.Stage("s", "tiny.toml", select="validation:noise"),
        tmp_path / "run",
        styles=1,
        res=48,  # patches to compare
        spp=1,
        densities=[blob_density],
    )
    assert "smooth noise" in against_noise.reason and all(np.isfinite(list(against_noise.scores.values())))
    with pytest.raises(ValueError, match="no kept checkpoint of step 5"):
        recipes.select(recipes.Stage("s", "tiny.toml", select="step:5"), tmp_path / "run")


@pytest.mark.parametrize("extra, message", [(("--resume",), "No checkpoint at"), (("--init", "nope.pt"), "nope.pt")])
def test_a_run_that_cannot_start_leaves_no_folder(tmp_path, tiny_smoke, extra, message):
    out = tmp_path / "run"
    result = run(out, tiny_smoke, *extra, check=False)
    assert result.returncode == 2 and message in result.stderr and "Traceback" not in result.stderr
    assert not out.exists()


def test_a_frame_of_another_shape_is_named(tiny_smoke, tmp_path):
    """A frame file replaced by one of another grid size once ended in numpy's "all input arrays must have
    the same shape", naming no file."""
    from mistyle.train.dataset import SmokePairs

    root = tmp_path / "smoke"
    shutil.copytree(tiny_smoke, root)
    data = SmokePairs(root, log=lambda *a: None)
    pair = data.train[0]
    with np.load(pair.second) as frame:
        arrays = {key: frame[key] for key in frame.files}
    arrays["density"] = arrays["density"][:4]
    np.savez(pair.second, **arrays)
    with pytest.raises(ValueError, match=f"{pair.second.name} holds a .* density; the dataset's frames are"):
        data.load(pair)
