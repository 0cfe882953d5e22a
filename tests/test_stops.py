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


def test_sigterm_during_a_long_path_trace_ends_the_render_within_two_seconds(tmp_path, blob_density):
    """A 256^2 render at 1024 spp takes minutes; it runs in passes (``pathtrace.PASS_SAMPLES``) so that
    SIGTERM ends it with the stop's one line and nothing left beside the output (no lock, no staging)."""
    import os
    import select
    from pathlib import Path

    from mistyle.files import write_vol

    density = tmp_path / "in" / "blob.vol"
    density.parent.mkdir()
    write_vol(density, blob_density)
    renders = tmp_path / "renders"
    renders.mkdir()
    style = Path(__file__).resolve().parents[1] / "examples" / "style_marble.png"
    command = [sys.executable, "-m", "mistyle.render_final", "--density", str(density), "--style", str(style)]
    command += ["--out", str(renders / "blob"), "--res", "256", "--spp", "1024", "--refine", "0"]
    environment = {**os.environ, "MISTYLE_PROGRESS": "lines"}  # the bars as lines on a pipe
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=environment)
    try:
        progress, deadline = b"", time.monotonic() + 60
        while b"path tracing" not in progress and time.monotonic() < deadline and process.poll() is None:
            if select.select([process.stderr], [], [], 0.5)[0]:
                progress += os.read(process.stderr.fileno(), 65536)
        assert b"path tracing" in progress, progress.decode()
        time.sleep(1.0)  # into the passes
        assert process.poll() is None, "the render ended before it was stopped"
        sent = time.monotonic()
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=60)
        took = time.monotonic() - sent
        error = (progress + process.stderr.read()).decode()
        assert process.returncode == TERMINATED_CODE, error
        assert took < 2.0, f"SIGTERM took {took:.2f} s to end the render"
        lines = [line.strip() for line in error.replace("\r", "\n").splitlines() if line.strip()]
        assert lines[-1] == "terminated: the output being written was removed; finished outputs are kept"
        assert sum("terminated" in line for line in lines) == 1 and "Traceback" not in error
        assert "path traced" not in error and process.stdout.read() == b""  # stopped during the path trace
        assert sorted(p.name for p in renders.iterdir()) == []  # no .lock, no .blob.partial-*
    finally:
        if process.poll() is None:  # a failed check leaves no render running
            process.kill()
            process.wait()


def test_a_threads_own_check_ends_a_solid_texture_at_its_next_step_and_only_in_that_thread():
    """``stops.checking``: the live preview's next style ends a look's fit inside its longest stage
    before the first step (the style's solid texture), in the worker's thread alone."""
    import threading

    import numpy as np

    from mistyle.solid_texture import SolidTextureSettings, synthesise_solid_texture

    class Changed(Exception):
        pass

    steps = []

    def check():
        steps.append(1)
        if len(steps) == 3:
            raise Changed

    style = np.random.default_rng(0).random((32, 32, 3)).astype(np.float32)
    settings = SolidTextureSettings(side=16, levels=1, steps=50)
    with stops.checking(check):
        other = threading.Thread(target=stops.raise_if_requested)  # another thread's safe point: no check
        other.start()
        other.join()
        with pytest.raises(Changed):
            synthesise_solid_texture(style, settings)
    assert len(steps) == 3
    stops.raise_if_requested()  # outside it, nothing is checked
    assert len(steps) == 3
