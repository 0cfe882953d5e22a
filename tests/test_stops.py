"""Every command stops on Ctrl-C or SIGTERM with one line and the shell's code, never a traceback."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

from mistyle import stops
from mistyle.stops import INTERRUPTED_CODE, TERMINATED_CODE, run_stoppable


@pytest.mark.parametrize(
    "handler, code, word",
    [(stops.on_sigint, INTERRUPTED_CODE, "interrupted"), (stops.on_sigterm, TERMINATED_CODE, "terminated")],
)
@pytest.mark.parametrize("chained", [True, False], ids=["caused-by-the-signal", "cause-lost"])
def test_a_stop_that_a_library_wrapped_in_another_error_is_still_a_stop(capsys, handler, code, word, chained):
    """A signal that lands inside Dr.Jit's custom operations reaches Python as a RuntimeError, with the
    signal's exception as its cause or without it."""

    def work():
        try:
            handler(None, None)
        except BaseException as cause:
            error = RuntimeError("drjit.custom(<LayerOp>): error while performing a custom operation")
            raise error from (cause if chained else None)

    assert run_stoppable(work, "nothing was kept", in_process=True) == code
    assert capsys.readouterr().err == f"{word}: nothing was kept\n"


def test_other_errors_pass_through_and_the_handlers_are_restored():
    before = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)

    def work():
        assert signal.getsignal(signal.SIGTERM) is stops.on_sigterm
        raise ValueError("bad input")

    with pytest.raises(ValueError, match="bad input"):
        run_stoppable(work, "kept", in_process=True)
    assert (signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)) == before
    assert run_stoppable(lambda: 0, "kept", in_process=True) == 0


def test_a_benchmark_stopped_by_ctrl_c_keeps_its_rows_and_says_how_to_go_on(mi, tmp_path):
    out = tmp_path / "bench"
    command = [
        sys.executable,
        "-m",
        "mistyle.benchmark",
        "--quick",
        "--methods",
        "uniform,smooth_noise",
        "--out",
        str(out),
    ]
    command += ["--cache", str(tmp_path / "cache")]
    # A test run started in the background has SIGINT ignored, and a child inherits that; a terminal's
    # foreground process has the default action.
    process = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    deadline = time.time() + 120
    while not (out / "rows.jsonl").exists() and time.time() < deadline:
        time.sleep(0.1)
    assert (out / "rows.jsonl").exists(), "the benchmark never wrote a row"
    process.send_signal(signal.SIGINT)
    _, error = process.communicate(timeout=120)
    assert process.returncode == INTERRUPTED_CODE, error
    assert error.strip().splitlines()[-1] == (
        f"interrupted: the rows scored so far are kept in {out / 'rows.jsonl'}; add --resume to go on from them"
    )
    assert "Traceback" not in error and (out / "rows.jsonl").read_text().strip()


@pytest.mark.parametrize("safe_points", [3, 0], ids=["at-the-next-step", "at-the-end"])
def test_a_stop_whose_exception_was_lost_still_stops_the_run(capsys, safe_points):
    """Raised while the interpreter runs a finalizer, a handler's exception is printed as ignored and the
    run goes on; the loops' safe points (or the end of the work) raise it again."""
    steps = []

    def work():
        try:
            stops.on_sigint(None, None)
        except KeyboardInterrupt:
            pass  # lost
        for step in range(safe_points):
            stops.raise_if_requested()
            steps.append(step)
        return 0

    assert run_stoppable(work, "kept", in_process=True) == INTERRUPTED_CODE
    assert steps == [] and capsys.readouterr().err == "interrupted: kept\n"
    stops.raise_if_requested()  # once the run is over, library calls are not stopped by its signal
