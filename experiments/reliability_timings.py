"""How fast the commands stop and refuse, measured on real subprocesses (issues #52 and #53).

- SIGTERM and SIGINT during a long path trace (``mistyle-render --res 256 --spp 1024``): seconds from the
  signal to the exit, the exit code, and what is left beside the output.
- ``mistyle-farm`` with a bad ``--out`` (a file; a folder of the user's) and a bad pass-through option:
  seconds to the one-line error, and whether any worker started.
- Ctrl-C (SIGINT to the process group) on a two-worker farm while both workers path trace: seconds to
  the exit, the exit code, and what is left.

    python experiments/reliability_timings.py [--repeats 3] [--out results/reliability]

Writes ``timings.json`` (every run) and ``timings.md`` (medians and ranges) into ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import select
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
STYLE = REPO / "examples" / "style_marble.png"


def small_density(folder: Path) -> Path:
    """The bundled smoke, halved to 32^3: the network's part stays short, the path trace is what is timed."""
    from mistyle.files import read_vol, write_vol

    density = read_vol(REPO / "examples" / "smoke_64.vol")
    half = density.reshape(32, 2, 32, 2, 32, 2).mean(axis=(1, 3, 5))
    path = folder / "smoke_32.vol"
    write_vol(path, half.astype(np.float32))
    return path


def wait_for(process, text: bytes, seconds: float) -> bytes:
    seen, deadline = b"", time.monotonic() + seconds
    while text not in seen and time.monotonic() < deadline and process.poll() is None:
        if select.select([process.stderr], [], [], 0.2)[0]:
            seen += os.read(process.stderr.fileno(), 65536)
    return seen


def signal_during_path_trace(folder: Path, density: Path, name: str) -> dict:
    out = folder / f"renders-{name}-{time.monotonic_ns()}"
    out.mkdir()
    command = [sys.executable, "-m", "mistyle.render_final", "--density", str(density), "--style", str(STYLE)]
    command += ["--out", str(out / "shot"), "--res", "256", "--spp", "1024", "--refine", "0"]
    process = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**os.environ, "MISTYLE_PROGRESS": "lines"},
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    reached = b"path tracing" in wait_for(process, b"path tracing", 120)
    time.sleep(1.0)
    sent = time.perf_counter()
    process.send_signal(getattr(signal, name))
    process.wait(timeout=300)
    return {
        "case": f"{name} during a 256^2 x 1024 spp path trace",
        "reached_path_trace": reached,
        "seconds_to_exit": time.perf_counter() - sent,
        "exit_code": process.returncode,
        "left_beside_output": sorted(p.name for p in out.iterdir()),
    }


def farm_inputs(folder: Path, density: Path) -> tuple[Path, Path]:
    from mistyle.files import read_vol, write_vol

    frames = folder / "frames"
    frames.mkdir()
    grid = read_vol(density)
    for index in range(4):
        write_vol(frames / f"f_{index:02d}.vol", np.roll(grid, index, axis=2))
    look = folder / "smoke.look"
    fit = [sys.executable, "-m", "mistyle.render_final", "--density", str(frames), "--style", str(STYLE)]
    fit += ["--save-look", str(look), "--look-steps", "1", "--quiet"]
    subprocess.run(fit, check=True)
    return frames, look


def farm_refusal(folder: Path, frames: Path, look: Path, case: str, out: Path, *extra: str) -> dict:
    command = [sys.executable, "-m", "mistyle.farm", "--local-workers", "2", "--density", str(frames)]
    command += ["--look", str(look), "--out", str(out), *extra]
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, timeout=300)
    lines = done.stderr.strip().splitlines()
    return {
        "case": f"mistyle-farm {case}",
        "seconds_to_error": time.perf_counter() - started,
        "exit_code": done.returncode,
        "stderr_lines": len(lines),
        "error": (lines[-1] if lines else "").replace(str(folder), "SCRATCH"),  # no machine paths in results
        "workers_started": "worker" in done.stderr.lower() and "Traceback" in done.stderr,
    }


def farm_ctrl_c(folder: Path, frames: Path, look: Path) -> dict:
    out = folder / f"farm-{time.monotonic_ns()}" / "fb"
    scratch = folder / f"tmp-{time.monotonic_ns()}"
    scratch.mkdir()
    command = [sys.executable, "-m", "mistyle.farm", "--local-workers", "2", "--density", str(frames)]
    command += ["--look", str(look), "--out", str(out), "--chunk", "1", "--", "--res", "64", "--spp", "512"]
    process = subprocess.Popen(
        command,
        env={**os.environ, "TMPDIR": str(scratch)},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    deadline = time.time() + 300
    while len(list(out.parent.glob(f".{out.name}.chunk-*/shipped.look"))) < 2 and time.time() < deadline:
        time.sleep(0.05)
    time.sleep(1.0)
    running = process.poll() is None
    os.killpg(process.pid, signal.SIGINT)
    sent = time.perf_counter()
    _, error = process.communicate(timeout=300)
    return {
        "case": "Ctrl-C on a two-worker farm while both workers path trace",
        "running_when_interrupted": running,
        "seconds_to_exit": time.perf_counter() - sent,
        "exit_code": process.returncode,
        "stderr_lines": len(error.strip().splitlines()),
        "left_beside_output": sorted(p.name for p in out.parent.glob(f".{out.name}.*")),
        "left_in_tmp": sorted(p.name for p in scratch.iterdir()),
    }


def summary(rows: list[dict]) -> str:
    lines = [
        "# How fast the commands stop and refuse",
        "",
        f"Made by `python experiments/reliability_timings.py`; machine: {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the end. Seconds, median (min-max).",
        "",
        "| case | runs | seconds | exit codes | left behind |",
        "| --- | --- | --- | --- | --- |",
    ]
    for case in dict.fromkeys(row["case"] for row in rows):
        group = [row for row in rows if row["case"] == case]
        key = "seconds_to_exit" if "seconds_to_exit" in group[0] else "seconds_to_error"
        seconds = [row[key] for row in group]
        left = sorted(
            {name for row in group for name in [*row.get("left_beside_output", []), *row.get("left_in_tmp", [])]}
        )
        codes = sorted({row["exit_code"] for row in group})
        lines.append(
            f"| {case} | {len(group)} | {np.median(seconds):.2f} ({min(seconds):.2f}-{max(seconds):.2f}) | "
            f"{', '.join(map(str, codes))} | {', '.join(left) or 'nothing'} |"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=REPO / "results" / "reliability")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch)
        density = small_density(folder)
        for _ in range(args.repeats):
            for name in ("SIGTERM", "SIGINT"):
                rows.append(signal_during_path_trace(folder, density, name))
                print(json.dumps(rows[-1]), flush=True)
        frames, look = farm_inputs(folder, density)
        afile = folder / "notes.txt"
        afile.write_text("mine")
        users = folder / "shots"
        users.mkdir()
        (users / "plan.txt").write_text("my notes")
        for _ in range(args.repeats):
            rows.append(farm_refusal(folder, frames, look, "--out a file", afile))
            rows.append(farm_refusal(folder, frames, look, "--out a folder of the user's", users))
            rows.append(farm_refusal(folder, frames, look, "-- --out elsewhere", folder / "fb", "--", "--out", "x"))
            rows.append(farm_refusal(folder, frames, look, "-- --bogus", folder / "fb", "--", "--bogus"))
            rows.append(farm_ctrl_c(folder, frames, look))
            print(json.dumps(rows[-1]), flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "timings.json").write_text(json.dumps(rows, indent=1) + "\n")
    (args.out / "timings.md").write_text(summary(rows))
    print(summary(rows))


if __name__ == "__main__":
    main()
