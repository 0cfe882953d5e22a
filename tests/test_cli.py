"""The console commands of pyproject.toml and their ``python -m`` forms."""

import subprocess
import sys
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent


@pytest.mark.parametrize("command, module", [("mistyle-render", "mistyle.render_final"), ("mistyle-train", "mistyle.train"),
                                             ("mistyle-data", "mistyle.data")])
def test_console_commands_and_module_forms_run(command, module):
    script = BIN / command
    assert script.is_file(), f"{script} missing: run `make setup` (pip install -e .) to install the console commands"
    for argv in ([str(script), "--help"], [sys.executable, "-m", module, "--help"]):
        done = subprocess.run(argv, capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        assert f"usage: {command}" in done.stdout and "--quiet" in done.stdout


def test_progress_is_off_when_stderr_is_not_a_terminal(tmp_path):
    """Through a pipe, data generation prints its status lines and no bar (no carriage returns)."""
    done = subprocess.run([str(BIN / "mistyle-data"), "smoke", "--res", "16", "--plumes", "2", "--frames", "3",
                           "--directions", "8", "--out", str(tmp_path / "smoke")], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "plume 1: " in done.stderr and "\r" not in done.stderr and "simulating plumes" not in done.stderr
    quiet = subprocess.run([str(BIN / "mistyle-data"), "--quiet", "smoke", "--res", "16", "--plumes", "2", "--frames", "3",
                            "--directions", "8", "--out", str(tmp_path / "smoke")], capture_output=True, text=True, timeout=600)
    assert quiet.returncode == 0 and quiet.stderr == "", quiet.stderr
