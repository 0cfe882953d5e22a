"""``mistyle-farm``, ``mistyle-train``, ``mistyle-data`` and ``mistyle-bench`` check everything before they
start (one line, exit 2), never write over a user's files, and leave nothing behind when stopped (#53)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from mistyle.files import write_vol

REPO = Path(__file__).resolve().parents[1]
TINY = str(REPO / "configs" / "tiny.toml")
FAST = ["--res", "16", "--spp", "1"]


def command(module: str, *arguments, env=None, timeout=300) -> subprocess.CompletedProcess:
    """``python -m module arguments``, timed (``.seconds``)."""
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", module, *map(str, arguments)],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=timeout,
        env=None if env is None else {**os.environ, **env},
    )
    done.seconds = time.perf_counter() - started
    return done


def one_line_error(done, *words) -> None:
    """Exit 2 with one line on stderr holding each of ``words``, and no traceback."""
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: "), done.stderr[-3000:]
    assert all(word in lines[0] for word in words), lines[0]


def contents(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def staging_beside(out: Path) -> list[str]:
    """The staging folders and locks beside the output ``out``."""
    return sorted(p.name for p in out.parent.glob(f".{out.name}.*"))


# ---------------------------------------------------------------------------- the farm
@pytest.fixture(scope="module")
def farm_inputs(tmp_path_factory, blob_density, tiny_checkpoint_factory):
    """A tiny checkpoint, four moving frames and a look fitted on them (``--save-look``)."""
    from mistyle.render_final import main

    folder = tmp_path_factory.mktemp("farm")
    checkpoint = tiny_checkpoint_factory(folder / "tiny.pt")
    frames = folder / "frames"
    frames.mkdir()
    for index in range(4):
        write_vol(frames / f"f_{index:02d}.vol", np.roll(blob_density, index, axis=2))
    Image.fromarray((np.random.default_rng(2).random((32, 32, 3)) * 255).astype(np.uint8)).save(folder / "s.png")
    look = folder / "s.look"
    fit = ["--density", frames, "--style", folder / "s.png", "--save-look", look, "--look-steps", "1"]
    assert main([*map(str, fit), "--checkpoint", str(checkpoint), *FAST, "--quiet"]) == 0
    return {"checkpoint": checkpoint, "frames": frames, "look": look}


def farm(inputs, out, *extra, workers=2, **kwargs):
    where = ["--local-workers", workers, "--density", inputs["frames"], "--look", inputs["look"], "--out", out]
    return command("mistyle.farm", *where, *extra, **kwargs)


@pytest.mark.parametrize(
    "passed, words",
    [
        (["--out", "{elsewhere}"], ["--out is mistyle-farm's own option", "before --"]),
        (["--ou", "{elsewhere}"], ["--out is mistyle-farm's own option"]),  # argparse's abbreviation of --out
        (["--frames", "0-1"], ["--frames is mistyle-farm's own option"]),
        (["--density", "{elsewhere}"], ["--density is mistyle-farm's own option"]),
        (["--bogus"], ["after --", "unrecognized arguments: --bogus"]),
        (["--spp", "-1"], ["--spp must lie in [1, 65536], got -1"]),
    ],
    ids=["out", "out-abbreviated", "frames", "density", "unknown", "out-of-range"],
)
def test_farm_checks_what_it_passes_to_every_chunk_before_starting_workers(farm_inputs, tmp_path, passed, words):
    """``-- --out elsewhere`` once wrote the frames to ``elsewhere`` and said it wrote ``--out`` (exit 0); an
    unknown option ended in ``FutureCancelledError``, after the cluster had started (about 40 s)."""
    out, elsewhere = tmp_path / "fb", tmp_path / "elsewhere"
    options = [item.format(elsewhere=elsewhere) for item in passed]
    done = farm(farm_inputs, out, "--", "--checkpoint", farm_inputs["checkpoint"], *FAST, *options)
    one_line_error(done, *words)
    assert done.seconds < 5, f"{done.seconds:.1f} s: the check came after the workers started"
    assert not out.exists() and not elsewhere.exists() and list(tmp_path.iterdir()) == []


def test_farm_refuses_a_bad_out_before_starting_workers(farm_inputs, tmp_path):
    """A file, or a folder holding a user's files, once failed inside every worker, with Dask's tracebacks."""
    afile = tmp_path / "notes.txt"
    afile.write_text("mine")
    done = farm(farm_inputs, afile)
    one_line_error(done, f"The output path {afile} is a file")
    assert done.seconds < 5 and afile.read_text() == "mine"

    mine = tmp_path / "shots"
    mine.mkdir()
    (mine / "plan.txt").write_text("my notes")
    done = farm(farm_inputs, mine)
    one_line_error(done, "shots holds plan.txt", "mistyle replaces only its own files")
    assert done.seconds < 5 and contents(mine) == {"plan.txt": b"my notes"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt", "shots"]  # no lock or staging left


def test_farm_names_a_scheduler_address_that_does_not_answer(farm_inputs, tmp_path, monkeypatch):
    """Dask's own words ("missing port number in address", a time-out) named neither the option nor a fix."""
    import argparse

    from mistyle import farm as farm_module

    out = tmp_path / "fb"
    where = ["--scheduler", "notanaddress", "--density", farm_inputs["frames"], "--look", farm_inputs["look"]]
    done = command("mistyle.farm", *where, "--out", out, "--", "--checkpoint", farm_inputs["checkpoint"], *FAST)
    one_line_error(done, "--scheduler notanaddress: no Dask scheduler answered there", "leave --scheduler out")
    assert not out.exists()
    monkeypatch.setattr(farm_module, "SCHEDULER_TIMEOUT", 1)  # nothing listens on port 1
    with pytest.raises(ValueError, match="tcp://127.0.0.1:1: no Dask scheduler answered there .*Timed out"):
        with farm_module._cluster(argparse.Namespace(scheduler="tcp://127.0.0.1:1")):
            pass


def test_a_killed_chunk_leaves_nothing_that_the_next_run_does_not_remove(farm_inputs, tmp_path):
    """A chunk killed with SIGKILL leaves its staging folders (the render's and the shipped look's, both
    named after its process); the next chunk into the same folder removes them. The look once went to a
    ``mistyle-look-*`` folder in the temporary directory that nothing removed."""
    from mistyle.farm import chunk_settings, render_chunk

    out, scratch = tmp_path / "shots" / "fb", tmp_path / "tmp"
    scratch.mkdir()
    slow = ["--checkpoint", str(farm_inputs["checkpoint"]), "--res", "64", "--spp", "256"]
    script = (
        "import sys; from pathlib import Path; from mistyle.farm import chunk_settings, render_chunk\n"
        "settings = chunk_settings(sys.argv[4:])\n"
        "render_chunk(Path(sys.argv[1]).read_bytes(), sys.argv[2], sys.argv[3], 0, 3, *settings)\n"
    )
    process = subprocess.Popen(
        [sys.executable, "-c", script, farm_inputs["look"], farm_inputs["frames"], out, *slow],
        env={**os.environ, "TMPDIR": str(scratch)},
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.time() + 120
    while len(staging_beside(out)) < 2 and time.time() < deadline:  # the look's, then the render's
        time.sleep(0.05)
    process.kill()
    process.wait(timeout=60)
    left = staging_beside(out)
    assert len(left) == 2 and all(".chunk-" in name for name in left), left

    settings = chunk_settings(slow[:2] + FAST)
    result = render_chunk(farm_inputs["look"].read_bytes(), str(farm_inputs["frames"]), str(out), 0, 0, *settings)
    assert result == {"frames": [0, 0]}
    assert staging_beside(out) == [] and (out / "sequence_0000.exr").is_file()
    assert list(scratch.iterdir()) == []


def test_ctrl_c_stops_a_two_worker_farm_at_once_and_leaves_nothing(farm_inputs, tmp_path):
    """Ctrl-C (SIGINT to the terminal's process group) on a two-worker farm: exit 130 within 5 s, one line,
    no chunk staging beside the output, no temporary folder. It once printed CancelledError tracebacks
    and a leaked-semaphore warning and left ``.NAME.chunk-*`` and ``mistyle-look-*`` folders."""
    out, scratch = tmp_path / "shots" / "fb", tmp_path / "tmp"
    scratch.mkdir()
    argv = ["--local-workers", "2", "--density", farm_inputs["frames"], "--look", farm_inputs["look"], "--out", out]
    slow = ["--checkpoint", farm_inputs["checkpoint"], "--res", "64", "--spp", "256"]
    process = subprocess.Popen(
        [sys.executable, "-m", "mistyle.farm", *map(str, argv), "--chunk", "1", "--", *map(str, slow)],
        cwd=REPO,
        env={**os.environ, "TMPDIR": str(scratch)},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's foreground job
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # a background test run ignores it
    )
    deadline = time.time() + 180
    while len(list(out.parent.glob(f".{out.name}.chunk-*/shipped.look"))) < 2 and time.time() < deadline:
        time.sleep(0.05)
    assert process.poll() is None, process.communicate()
    time.sleep(1)  # both workers inside their path trace
    os.killpg(process.pid, signal.SIGINT)
    stopped = time.perf_counter()
    _, error = process.communicate(timeout=60)
    seconds = time.perf_counter() - stopped
    assert process.returncode == 130, error
    assert error.strip().splitlines() == [f"interrupted: the frames finished so far are kept in {out}"], error
    assert seconds < 5, f"{seconds:.1f} s from Ctrl-C to exit"
    assert staging_beside(out) == [] and list(scratch.iterdir()) == []


# ---------------------------------------------------------------------------- training
def train(capsys, out, *extra, smoke) -> subprocess.CompletedProcess:
    """``mistyle-train`` in this process (``main(argv)``): its exit code and what it printed."""
    from mistyle.train.__main__ import main

    capsys.readouterr()
    code = main(["--config", TINY, "--out", str(out), "--set", f'data.smoke="{smoke}"', *map(str, extra)])
    printed = capsys.readouterr()
    return subprocess.CompletedProcess([], code, printed.out, printed.err)


def test_train_refuses_a_folder_of_the_users_files_and_changes_nothing(tmp_path, tiny_smoke, capsys):
    """``--out`` holding the user's own ``config.toml`` and ``metrics.jsonl``: the config was overwritten,
    then ``KeyError: 'step'`` in ``_trim_metrics``."""
    out = tmp_path / "USERRUN"
    out.mkdir()
    (out / "config.toml").write_text("[mine]\nkeep = true\n")
    (out / "metrics.jsonl").write_text('{"loss": 1.0}\n')
    before = contents(out)
    done = train(capsys, out, "--set", "optim.steps=2", smoke=tiny_smoke)
    one_line_error(done, "USERRUN holds config.toml, metrics.jsonl", "choose another --out")
    assert contents(out) == before and sorted(p.name for p in tmp_path.iterdir()) == ["USERRUN"]


def _tensor_offset(path: Path) -> tuple[int, int]:
    """Where the bytes of the checkpoint's largest tensor lie in its file: ``(offset, size)``."""
    with zipfile.ZipFile(path) as archive:
        entry = max((e for e in archive.infolist() if "/data/" in e.filename), key=lambda e: e.file_size)
    with open(path, "rb") as handle:
        handle.seek(entry.header_offset + 26)
        name, extra = np.frombuffer(handle.read(4), np.uint16)
    return entry.header_offset + 30 + int(name) + int(extra), entry.file_size


def test_a_training_run_records_its_files_and_a_damaged_checkpoint_is_named(tmp_path, tiny_smoke, capsys):
    """A run folder's manifest (kind ``train``) lists what the run wrote; resuming from a ``last.pt`` whose
    bytes were damaged once failed with "albedo holds NaN or inf values", naming neither file nor cause."""
    from mistyle.ownership import is_owned, read_manifest

    out = tmp_path / "run"
    settings = ["--set", "optim.steps=2", "--set", "run.checkpoint_every=2", "--set", "run.eval_every=100"]
    done = train(capsys, out, *settings, "--quiet", smoke=tiny_smoke)
    assert done.returncode == 0, done.stderr[-3000:]
    record = read_manifest(out)
    assert record["kind"] == "train" and "pending" not in record and is_owned(out)
    assert {"config.toml", "metrics.jsonl", "last.pt", "final.pt"} <= set(record["files"])

    offset, size = _tensor_offset(out / "last.pt")
    data = bytearray((out / "last.pt").read_bytes())
    data[offset : offset + min(size, 64)] = b"\xff" * min(size, 64)  # NaNs in float32
    (out / "last.pt").write_bytes(bytes(data))
    done = train(capsys, out, "--resume", "--set", "optim.steps=4", smoke=tiny_smoke)
    one_line_error(done, f"{out / 'last.pt'} is damaged")


def test_an_older_checkpoint_with_nan_weights_names_its_file(tmp_path, tiny_checkpoint_factory):
    """A checkpoint without the tensors' digest (an older mistyle's, or written by torch.save) is still
    checked for finite tensors when loaded."""
    import torch

    from mistyle.model.checkpoint import load_checkpoint, load_model

    path = tiny_checkpoint_factory(tmp_path / "old.pt")
    checkpoint = torch.load(path, weights_only=True)
    name = next(key for key, value in checkpoint["model"].items() if value.is_floating_point())
    checkpoint["model"][name][...] = float("nan")
    torch.save(checkpoint, path)
    for loader in (load_checkpoint, load_model):
        with pytest.raises(ValueError, match=f"{path}: model/{name} holds NaN or inf values"):
            loader(path)


# ---------------------------------------------------------------------------- datasets
@pytest.mark.parametrize(
    "argv, message",
    [
        (
            ["smoke", "--res", "16", "--plumes", "1", "--frames", "4", "--density-scale", "-1"],
            "--density-scale must lie in (0, 1e+06], got -1.0",
        ),
        (["smoke", "--plumes", "0"], "--plumes must lie in [1, 100000], got 0"),
        (["smoke", "--directions", "0"], "--directions must lie in [1, 4096], got 0"),
        (["smoke", "--seed", "-3"], "--seed must lie in [0, 2147483647], got -3"),
        (["smoke", "--crops-per-frame", "0", "--crop", "8"], "--crops-per-frame must lie in [1, 1000], got 0"),
        (["styles", "--size", "0"], "--size must lie in [8, 512] pixels, got 0"),
        (["styles", "--size", "100000"], "--size must lie in [8, 512] pixels, got 100000"),
        (["fire", "--keep", "5-2"], "--keep 5-2: the kept frames must lie within 1-120 (first <= last)"),
        (["mesh", "--supersample", "0", "--out", "{out}.vol"], "--supersample must lie in [1, 8], got 0"),
    ],
)
def test_data_checks_every_option_before_any_work(tmp_path, capsys, argv, message):
    """``smoke --density-scale -1`` once made a dataset (exit 0) with an Ls grid of 1.0 everywhere;
    ``styles --size 0`` was a traceback and ``--size 100000`` asked for 120 GB."""
    from mistyle.data.__main__ import main

    out = tmp_path / "out"
    argv = [item.format(out=out) for item in argv]
    assert main([*argv, *([] if "--out" in argv else ["--out", str(out)])]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert error == [f"error: {message}."], error
    assert list(tmp_path.iterdir()) == []


def test_data_refuses_a_file_or_a_users_folder_and_writes_nothing(tmp_path, capsys):
    """``tiny --out A_FILE`` was a ``NotADirectoryError`` traceback; a folder of the user's files is refused
    before it could be written into."""
    from mistyle.data.__main__ import main

    afile = tmp_path / "A_FILE"
    afile.write_text("mine")
    assert main(["tiny", "--out", str(afile)]) == 2
    assert capsys.readouterr().err == f"error: The output path {afile} is a file; choose a folder for --out.\n"
    mine = tmp_path / "styles"
    mine.mkdir()
    (mine / "holiday.png").write_bytes(b"a photo")
    assert main(["styles", "--size", "8", "--out", str(mine)]) == 2
    assert "styles holds holiday.png" in capsys.readouterr().err
    assert afile.read_text() == "mine" and contents(mine) == {"holiday.png": b"a photo"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["A_FILE", "styles"]


def test_a_dataset_folder_records_its_files_and_takes_over_an_older_ones(tmp_path, capsys):
    """The style set's folder carries a manifest (kind ``dataset``); a folder an older mistyle wrote
    (its layout alone, no manifest) is completed, one holding anything else is refused."""
    from mistyle.data.__main__ import main
    from mistyle.ownership import MANIFEST_FILE, is_owned, read_manifest

    out = tmp_path / "styles"
    assert main(["--quiet", "styles", "--size", "8", "--out", str(out)]) == 0
    assert read_manifest(out)["kind"] == "dataset" and is_owned(out) and len(read_manifest(out)["files"]) > 300
    (out / MANIFEST_FILE).unlink()  # as an older mistyle left it
    assert main(["--quiet", "styles", "--size", "8", "--out", str(out)]) == 0 and is_owned(out)
    (out / MANIFEST_FILE).unlink()
    (out / "photo" / "mine.txt").write_text("notes")
    assert main(["--quiet", "styles", "--size", "8", "--out", str(out)]) == 2
    assert "photo/mine.txt" in capsys.readouterr().err.splitlines()[-1]


# ---------------------------------------------------------------------------- the benchmark
@pytest.mark.parametrize(
    "argv, message",
    [
        (["--quick", "--optimise-factor", "-1"], "--optimise-factor must lie in (0, 100], got -1"),
        (["--quick", "--optimise-factor", "nan"], "--optimise-factor must lie in (0, 100], got nan"),
        (["--quick", "--res", "0"], "--res must lie in [8, 4096], got 0"),
        (["--quick", "--spp", "-1"], "--spp must lie in [1, 4096], got -1"),
    ],
)
def test_bench_checks_its_settings_also_with_quick(tmp_path, capsys, argv, message):
    """``--quick`` once ignored ``--res``/``--spp`` and recorded rows at factor -1 (exit 0)."""
    from mistyle.benchmark.__main__ import main

    assert main([*argv, "--out", str(tmp_path / "bench")]) == 2
    assert capsys.readouterr().err == f"error: {message}.\n"
    assert list(tmp_path.iterdir()) == []


def _rows(settings: list[dict]) -> str:
    """rows.jsonl of the uniform method on the quick split's two pairs, at each of ``settings``."""
    from mistyle.benchmark.splits import split_pairs

    lines = []
    for number, setting in enumerate(settings):
        for spec, style in split_pairs("quick"):
            row = dict(method="uniform", density=spec.name, style=style, rgb_swd=0.1 + number, patch_swd=0.2)
            row.update(hue_coverage=0.5, seconds=1.0, settings=setting, checkpoint="x.pt:0", commit="c", split="quick")
            lines.append(json.dumps(row))
    return "".join(line + "\n" for line in lines)


QUICK = {"res": 32, "spp": 4, "views": 3, "quick": True, "optimise_factor": 2.0}


def test_a_results_file_of_two_settings_gets_a_table_for_each(tmp_path, capsys):
    """Rows at two settings in one ``rows.jsonl`` were pooled: ``table.md`` said 4 pairs for the 2-pair
    quick split. Now each settings has its own table, under a line saying so."""
    from mistyle.benchmark.__main__ import main

    out = tmp_path / "bench"
    out.mkdir()
    (out / "rows.jsonl").write_text(_rows([QUICK, {**QUICK, "optimise_factor": 3.0}]))
    assert main(["--report-only", "--out", str(out)]) == 0
    table = (out / "table.md").read_text()
    assert table.startswith("rows.jsonl holds rows at 2 different settings; each has its own table")
    assert table.count(": 2 pairs\n") == 2 and "| 2 |\n" in table and "| 4 |" not in table
    assert "optimise_factor 3.0" in table and capsys.readouterr().out == table


def test_a_results_folders_notes_stay_and_do_not_stop_the_benchmark(tmp_path, capsys):
    """Every results folder has a README.md that people wrote; the benchmark refused any folder holding one."""
    from mistyle.benchmark.__main__ import main

    out = tmp_path / "bench"
    out.mkdir()
    (out / "rows.jsonl").write_text(_rows([QUICK]))
    assert main(["--report-only", "--out", str(out)]) == 0
    (out / "README.md").write_text("what made these rows\n")
    (out / "notes.txt").write_text("not the benchmark's\n")
    assert main(["--report-only", "--out", str(out)]) == 2
    assert "holds notes.txt: mistyle did not write them" in capsys.readouterr().err
    (out / "notes.txt").unlink()
    assert main(["--report-only", "--out", str(out)]) == 0
    assert (out / "README.md").read_text() == "what made these rows\n" and (out / "table.md").is_file()


@pytest.mark.parametrize(
    "damage, where",
    [(lambda data: data[: len(data) // 2 + 7], "line 2"), (lambda data: data + b"\x89PNG\r\n\x1a\n\xff", "line 3")],
    ids=["truncated", "binary"],
)
@pytest.mark.parametrize("mode", ["--report-only", "--resume"])
def test_a_damaged_results_file_is_named_with_its_line(tmp_path, capsys, damage, where, mode):
    """A truncated or binary ``rows.jsonl`` gave JSON's or UTF-8's own message, naming neither file nor fix."""
    from mistyle.benchmark.__main__ import main

    out = tmp_path / "bench"
    out.mkdir()
    (out / "rows.jsonl").write_bytes(damage(_rows([QUICK]).encode()))
    before = contents(out)
    assert main([mode, "--quick", "--methods", "uniform", "--out", str(out)]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and f"{out / 'rows.jsonl'}, {where}, is not a row of mistyle-bench" in error[0], error
    assert "restore it, delete that line" in error[0]
    assert contents(out) == before and sorted(p.name for p in tmp_path.iterdir()) == ["bench"]


def test_bench_out_a_file_is_one_line(tmp_path, capsys):
    """``--out`` a file was "[Errno 17] File exists"."""
    from mistyle.benchmark.__main__ import main

    afile = tmp_path / "results.txt"
    afile.write_text("mine")
    for mode in ([], ["--report-only"]):
        assert main(["--quick", *mode, "--out", str(afile)]) == 2
        assert capsys.readouterr().err == f"error: The output path {afile} is a file; choose a folder for --out.\n"
    assert afile.read_text() == "mine"
