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
