"""The benchmark package: its splits, its training-free baselines, its runner and rows, its command."""

import json
import shutil

import numpy as np
import pytest
from PIL import Image

from mistyle.benchmark import METHODS, split_pairs
from mistyle.benchmark.__main__ import main
from mistyle.benchmark.methods import density_ramp, smooth_noise, tuned_noise
from mistyle.benchmark.runner import TILE, read_rows, report, run, summary
from mistyle.benchmark.runner import table as table_of
from mistyle.data.heldout import HELD_OUT_SEED_BASE, HeldOutDensity, held_out_styles, validation_styles

TINY = HeldOutDensity("pyroclastic16", "pyroclastic", 16, HELD_OUT_SEED_BASE + 3)


def test_the_held_out_styles_are_package_data():
    from pathlib import Path

    import mistyle

    package = Path(mistyle.__file__).resolve().parent
    styles = held_out_styles()
    assert len(styles) >= 10
    assert all(package in record["path"].resolve().parents for record in styles.values())


def test_splits_name_their_pairs_and_refuse_unknown_names():
    pairs = split_pairs("heldout")
    assert {spec.name for spec, _ in pairs} == {"smoke64", "pyroclastic64"}
    assert len(pairs) == 2 * len(held_out_styles())
    assert [style for _, style in split_pairs("heldout", ["smoke64"], ["munch_the_scream"])] == ["munch_the_scream"]
    validation = split_pairs("validation")
    assert {spec.kind for spec, _ in validation} == {"smoke", "pyroclastic"}
    assert {style for _, style in validation} == set(validation_styles())
    assert not {style for _, style in validation} & set(held_out_styles())
    for bad, message in (
        (("nope",), "Unknown split"),
        (("validation", None, ["munch_the_scream"]), "no style munch_the_scream"),
        (("heldout", ["smoke32"]), "no density smoke32"),
        (("quick", None, ["munch_the_scream"]), "no style munch_the_scream"),
    ):
        with pytest.raises(ValueError, match=message):
            split_pairs(*bad)


def test_the_registry_holds_the_product_the_baselines_and_the_reference():
    roles = {name: method.role for name, method in METHODS.items()}
    assert {"default", "network"} <= {n for n, r in roles.items() if r == "product"}
    baselines = {"uniform", "density_ramp", "smooth_noise", "tuned_noise"}
    assert baselines <= {n for n, r in roles.items() if r == "baseline"}
    assert roles["optimised"] == "reference"
    assert not any(METHODS[name].uses_network for name in baselines)


def test_density_ramp_is_the_densitys_rank(rng):
    density = np.zeros((6, 7, 8), np.float32)
    density[1:5, 2:6, 3:7] = rng.random((4, 4, 4)) + 0.1
    ramp = density_ramp(density)
    assert ramp.shape == density.shape + (3,) and np.array_equal(ramp[..., 0], ramp[..., 2])
    occupied = density > 0
    assert np.all(ramp[~occupied] == 0) and ramp.max() == 1.0
    order = np.argsort(density[occupied])
    assert np.all(np.diff(ramp[..., 0][occupied][order]) > 0)  # strictly increasing with density


def seeded_rgb_field(make) -> np.ndarray:
    """``make(shape, seed=3)``, checked to be a seeded RGB field spanning [0, 1] per channel, with
    independent channels (colour varies in every direction)."""
    noise = make((32, 32, 32), seed=3)
    assert noise.shape == (32, 32, 32, 3) and noise.dtype == np.float32
    assert np.array_equal(noise, make((32, 32, 32), seed=3))
    assert not np.array_equal(noise, make((32, 32, 32), seed=4))
    assert np.allclose(noise.reshape(-1, 3).min(axis=0), 0) and np.allclose(noise.reshape(-1, 3).max(axis=0), 1)
    assert abs(np.corrcoef(noise.reshape(-1, 3).T)[0, 1]) < 0.5
    return noise


def test_smooth_noise_is_seeded_spans_the_unit_cube_and_is_smooth():
    noise = seeded_rgb_field(smooth_noise)
    # Neighbours are close: much closer than white noise's (mean |difference| 1/3 for uniform values).
    assert float(np.abs(np.diff(noise, axis=0)).mean()) < 0.05


def test_tuned_noise_is_seeded_coarser_than_smooth_noise_and_wraps_around_the_box():
    noise = seeded_rgb_field(tuned_noise)
    steps = float(np.abs(np.diff(noise, axis=0)).mean())
    assert steps < 0.75 * float(np.abs(np.diff(smooth_noise((32, 32, 32), seed=3), axis=0)).mean())  # coarser
    # Wrapped: the last slice continues into the first as smoothly as any two neighbours do.
    assert float(np.abs(noise[-1] - noise[0]).mean()) < 2 * steps


def test_runner_writes_rows_resumes_and_reports(mi, tmp_path):
    pairs = [(TINY, "hokusai_great_wave")]
    methods = ["density_ramp", "smooth_noise", "tuned_noise", "uniform"]
    lines = []
    out, cache = tmp_path / "bench", tmp_path / "cache"
    rows = run(out, pairs, methods, res=16, spp=1, cache=cache, log=lines.append)
    assert len(rows) == 4 and len(lines) == 4
    stored = read_rows(out / "rows.jsonl")
    assert [row.method for row in stored] == methods
    row = stored[0]
    assert row.density == "pyroclastic16" and row.settings["res"] == 16 and row.checkpoint.startswith("skpn_noise.pt:")
    assert np.isfinite([row.rgb_swd, row.patch_swd, row.hue_coverage]).all() and row.commit
    medians = summary(stored)
    assert medians["uniform"]["rgb_swd_x_uniform"] == 1.0 and medians["tuned_noise"]["patch_swd_x_tuned"] == 1.0
    table = (out / "table.md").read_text()
    assert all(f"| {name} |" in table for name in methods) and "| x tuned |" in table
    assert (out / "sheet.jpg").stat().st_size > 0 and (out / "index.html").exists()
    # Resume: nothing is recomputed; another setting gives rows of its own beside the first ones, and a
    # table of its own.
    lines.clear()
    run(out, pairs, methods, res=16, spp=1, cache=cache, resume=True, log=lines.append)
    assert lines == [] and read_rows(out / "rows.jsonl") == stored
    run(out, pairs, ["uniform"], res=16, spp=2, cache=cache, log=lines.append)
    assert len(read_rows(out / "rows.jsonl")) == 5
    assert "rows at 2 different settings" in (out / "table.md").read_text()
    # The validation split's pairs draw their styles from the validation set.
    pairs = [(HeldOutDensity("val_pyroclastic16", "pyroclastic", 16, HELD_OUT_SEED_BASE + 103), "klimt_the_kiss")]
    run(tmp_path / "validation", pairs, ["uniform"], res=16, spp=1, cache=cache, split="validation")
    assert [row.split for row in read_rows(tmp_path / "validation" / "rows.jsonl")] == ["validation"]
    assert (tmp_path / "validation" / "sheet.jpg").stat().st_size > 0
    # Without tuned_noise rows the ratios to it are n/a, not an error.
    assert "n/a" in table_of([row for row in stored if row.method != "tuned_noise"])
    # A clone holds the committed sheet without its tiles: the report keeps the sheet, not a grey one.
    sheet = (out / "sheet.jpg").read_bytes()
    shutil.rmtree(out / "tiles")
    (out / "table.md").unlink()
    report(out)
    assert (out / "sheet.jpg").read_bytes() == sheet and (out / "table.md").exists()
    # One method scored again there: the sheet shows it, not grey columns for the methods without tiles.
    run(out, [(TINY, "hokusai_great_wave")], ["uniform"], res=16, spp=1, cache=cache)
    with Image.open(out / "sheet.jpg") as image:
        assert image.width == 2 * TILE


def test_command_refuses_bad_input_in_one_line(tmp_path, capsys):
    assert (
        main(
            [
                "--methods",
                "network,magic",
                "--out",
                str(tmp_path / "x"),
                "--styles",
                "munch_the_scream",
                "--densities",
                "smoke64",
            ]
        )
        == 2
    )
    assert "Unknown method(s) magic" in capsys.readouterr().err
    assert main(["--report-only", "--out", str(tmp_path / "none")]) == 2
    assert "run the benchmark first" in capsys.readouterr().err
    assert main(["--split", "quick", "--styles", "munch_the_scream"]) == 2
    assert "no style munch_the_scream" in capsys.readouterr().err
    assert main(["--split", "quick", "--styles", "", "--out", str(tmp_path / "y")]) == 2
    assert "--styles names none" in capsys.readouterr().err and not (tmp_path / "y").exists()


@pytest.mark.benchmark
def test_quick_benchmark(mi, tmp_path, capsys):
    """``mistyle-bench --quick``: every method on the quick split, the table beside the baselines."""
    assert main(["--quick", "--out", str(tmp_path), "--cache", str(tmp_path / "cache")]) == 0
    rows = [json.loads(line) for line in (tmp_path / "rows.jsonl").read_text().splitlines()]
    assert {row["method"] for row in rows} == set(METHODS)
    assert len(rows) == len(METHODS) * len(split_pairs("quick"))
    table = capsys.readouterr().out
    assert "| smooth_noise |" in table and "| density_ramp |" in table and "| default |" in table


def test_resume_and_the_table_tell_one_network_from_another():
    """``--resume`` with another --checkpoint once kept the old network's rows, and a partial run blended
    two networks into one median without a word."""
    from mistyle.benchmark.runner import Row, check_methods, mixed_networks, same_network

    settings = {"res": 16, "spp": 1}

    def row(method, checkpoint, style="a"):
        return Row(method, "d", style, 0.1, 0.1, 0.5, 1.0, settings, checkpoint, "c", "heldout")

    assert not same_network(row("network", "one.pt:1"), row("network", "two.pt:2"))
    assert same_network(row("network", "one.pt:1"), row("network", "one.pt:1"))
    assert same_network(row("uniform", "one.pt:1"), row("uniform", "two.pt:2"))  # no network in it
    assert mixed_networks([row("network", "one.pt:1"), row("network", "two.pt:2", "b"), row("uniform", "x")]) == [
        "network"
    ]
    assert mixed_networks([row("network", "one.pt:1"), row("uniform", "two.pt:2")]) == []
    with pytest.raises(ValueError, match="names a method twice"):
        check_methods(["uniform", "uniform"])
    with pytest.raises(ValueError, match="Unknown method\\(s\\) ''"):
        check_methods(["uniform", ""])
