"""The console commands of pyproject.toml and their ``python -m`` forms."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent


@pytest.mark.parametrize(
    "command, module",
    [("mistyle-render", "mistyle.render_final"), ("mistyle-train", "mistyle.train"), ("mistyle-data", "mistyle.data")],
)
def test_console_commands_and_module_forms_run(command, module):
    script = BIN / command
    assert script.is_file(), f"{script} missing: run `make setup` (pip install -e .) to install the console commands"
    for argv in ([str(script), "--help"], [sys.executable, "-m", module, "--help"]):
        done = subprocess.run(argv, capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        assert f"usage: {command}" in done.stdout and "--quiet" in done.stdout


def test_the_render_commands_help_and_argument_errors_need_no_torch():
    """Importing torch costs seconds: ``--help`` and a bad option answer without it."""
    probe = (
        "import sys\n"
        "from mistyle.render_final import main\n"
        "code = main(['--density', 'missing.vol', '--style', 'missing.png', '--out', 'x', '--res', '-1'])\n"
        "print(code, 'torch' in sys.modules)"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300)
    assert done.stdout.split() == ["2", "False"], done.stdout + done.stderr


def test_progress_is_off_when_stderr_is_not_a_terminal(tmp_path):
    """Through a pipe, data generation prints its status lines and no bar (no carriage returns)."""
    done = subprocess.run(
        [
            str(BIN / "mistyle-data"),
            "smoke",
            "--res",
            "16",
            "--plumes",
            "2",
            "--frames",
            "3",
            "--directions",
            "8",
            "--out",
            str(tmp_path / "smoke"),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert "plume 1: " in done.stderr and "\r" not in done.stderr and "simulating plumes" not in done.stderr
    quiet = subprocess.run(
        [
            str(BIN / "mistyle-data"),
            "--quiet",
            "smoke",
            "--res",
            "16",
            "--plumes",
            "2",
            "--frames",
            "3",
            "--directions",
            "8",
            "--out",
            str(tmp_path / "smoke"),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert quiet.returncode == 0 and quiet.stderr == "", quiet.stderr


def test_data_on_a_device_this_machine_lacks_is_a_clear_error(tmp_path):
    """``--device`` picks the Ls precompute's Mitsuba variant; without a CUDA GPU, ``cuda`` is refused before any
    file is written, naming the fix, and a bad ``MISTYLE_DEVICE`` is named too."""
    import drjit as dr

    if dr.has_backend(dr.JitBackend.CUDA):
        pytest.skip("this machine has a CUDA GPU")
    out = tmp_path / "tiny"
    done = subprocess.run(
        [str(BIN / "mistyle-data"), "tiny", "--device", "cuda", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 2 and "error:" in done.stderr and "--device cpu" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr and not out.exists()
    bad = subprocess.run(
        [sys.executable, "-c", "from mistyle.backend import active_variant; active_variant()"],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "MISTYLE_DEVICE": "gpu"},
    )
    assert bad.returncode != 0 and "MISTYLE_DEVICE='gpu'" in bad.stderr and "'cpu' or 'cuda'" in bad.stderr


@pytest.mark.parametrize(
    "argv, message",
    [
        (["smoke", "--res", "100000"], "--res must lie in [8, 256] for smoke, got 100000"),
        (["smoke", "--res", "2048"], "--res must lie in [8, 256] for smoke, got 2048"),
        (["fire", "--res", "4"], "--res must lie in [8, 256] for fire, got 4"),
        (["mesh", "--res", "9999"], "--res must lie in [8, 512] for mesh, got 9999"),
    ],
)
def test_mistyle_data_bounds_sizes_before_any_work(tmp_path, capsys, argv, message):
    from mistyle.data.__main__ import main as data_main

    out = tmp_path / "out"
    assert data_main([*argv, "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_mistyle_data_keeps_the_last_frame_of_a_two_frame_run_by_default(mi, tmp_path):
    from mistyle.data.__main__ import main as data_main

    out = tmp_path / "smoke"
    assert data_main(["--quiet", "smoke", "--res", "8", "--plumes", "1", "--frames", "2", "--out", str(out)]) == 0
    frames = sorted(p.name for p in out.rglob("*.npz"))
    assert len(frames) == 1, frames  # frame 2 of 2, not "frames 3-2"
