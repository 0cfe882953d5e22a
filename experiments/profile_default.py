"""Where the default output's time goes: one 64^3 frame from process start to files written.

Runs ``mistyle-render`` with its defaults (a look fitted on the frame, one 256^2 view at 64 spp,
denoised) on the bundled smoke and style in a fresh process, ``--runs`` times, and splits each run's
wall time with the stage timings ``report.json`` records:

* ``start-up``: the interpreter, mistyle's, torch's and Mitsuba's imports (a separate process that
  only imports them, timed the same way),
* ``network + colour match`` (``stylize_seconds``), ``look fit`` (``look_seconds``),
* ``path trace + denoise`` (``render_seconds``: also the fast layer's images of the network's albedo),
* ``assets`` (grids, ``scene.xml``), ``metrics`` (the style metrics of ``report.json``),
* ``other``: the rest (reading the inputs, the checkpoint, writing the images).

The first run can be made **cold** (``--cold``): Dr.Jit's kernel cache (``~/.drjit``) starts empty, so
every kernel is compiled; the later runs are **warm** (compiled kernels come from the cache).

    python experiments/profile_default.py --runs 2 --cold       # results/profile_default/

``--baseline DIR`` (a checkout of other code, e.g. ``git worktree add ../before HEAD~3``) runs that
code's ``mistyle-render`` before each run of this checkout's, so both see the same machine, and adds
the ratios of their median stage times (this / baseline) to the table.

    python experiments/profile_default.py --runs 3 --baseline ../before

``--sequence N`` profiles a sequence instead: the first ``N`` frames from frame 60 of the held-out smoke
simulation (``data.heldout.held_out_sequence``, with its velocities), written as a folder of ``.npz``
frames; the table then also gives the seconds per frame.

    python experiments/profile_default.py --runs 1 --sequence 19 --out results/profile_default/sequence

Writes ``rows.jsonl`` and ``table.md`` under ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
STAGES = (
    ("network + colour match", "stylize_seconds"),
    ("look fit", "look_seconds"),
    ("path trace + denoise", "render_seconds"),
    ("assets", "assets_seconds"),
    ("metrics", "metrics_seconds"),
)
IMPORTS = "import mistyle.render_final, mistyle.pipeline, torch, mitsuba, drjit"


def timed(command: list[str], env: dict, cwd: Path = REPO) -> float:
    started = time.perf_counter()
    subprocess.run(command, check=True, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="results/profile_default")
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--cold", action="store_true", help="the first run with an empty Dr.Jit kernel cache")
    parser.add_argument("--baseline", type=Path, default=None, help="another checkout, run before each run of this one")
    parser.add_argument("--sequence", type=int, default=0, help="profile N frames of the held-out smoke instead")
    parser.add_argument("extra", nargs="*", help="more mistyle-render options, after --")
    args = parser.parse_args()
    from mistyle.benchmark.runner import code_commit

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    checkouts = ([("baseline", args.baseline.resolve())] if args.baseline else []) + [("this", REPO)]
    with tempfile.TemporaryDirectory() as scratch:
        density, frames = "examples/smoke_64.vol", 1
        if args.sequence:
            density, frames = str(write_sequence(Path(scratch) / "frames", args.sequence)), args.sequence
        for run in range(args.runs):
            for code, checkout in checkouts:
                env = dict(os.environ)
                cold = args.cold and run == 0
                if cold:  # Dr.Jit keeps its kernel cache under $HOME/.drjit
                    home = Path(scratch) / "home"
                    shutil.rmtree(home, ignore_errors=True)
                    home.mkdir()
                    env["HOME"] = str(home)
                target = Path(scratch) / f"run{run}_{code}"
                command = [
                    sys.executable,
                    "-m",
                    "mistyle.render_final",
                    "--density",
                    density,
                    "--style",
                    "examples/style_marble.png",
                    "--out",
                    str(target),
                    "--quiet",
                    *args.extra,
                ]
                # ``-m`` imports mistyle from the working directory: each checkout runs its own code.
                wall = timed(command, env, checkout)
                imports = timed([sys.executable, "-c", IMPORTS], env, checkout)
                report = json.loads((target / "report.json").read_text())
                row = {
                    "run": run,
                    "code": code,
                    "commit": code_commit(checkout),
                    "cache": "cold" if cold else "warm",
                    "wall_seconds": wall,
                    "frames": frames,
                    "start-up": imports,
                }
                for name, key in STAGES:
                    row[name] = float(report.get(key) or 0.0)
                row["other"] = wall - imports - sum(row[name] for name, _ in STAGES)
                row["load_average"] = os.getloadavg()[0]
                row["options"] = args.extra
                rows.append(row)
                print(json.dumps(row), flush=True)
    (out / "rows.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    write_table(out, rows, args)


def write_table(out: Path, rows: list[dict], args) -> None:
    """``table.md``: each run's stages, and with a baseline the ratios of the warm medians (none where
    the baseline's stage took under 0.05 s, e.g. a look fit that the baseline did not run)."""
    names = ["start-up"] + [name for name, _ in STAGES] + ["other"]
    frames = rows[0].get("frames", 1)
    density = "FRAMES/" if args.sequence else "examples/smoke_64.vol"
    lines = [
        f"The default output of {f'{frames} frames of the held-out smoke' if args.sequence else 'one 64^3 frame'} "
        f"(`mistyle-render --density {density} --style "
        f"examples/style_marble.png{' ' + ' '.join(args.extra) if args.extra else ''}`), seconds from process "
        f"start to files written; {os.cpu_count()} cores, load average (1 min) per run as given.",
        "",
        "| run | code | Dr.Jit kernels | total | per frame | " + " | ".join(names) + " | load |",
        "|---|---|---|---|---|" + "---|" * len(names) + "---|",
    ]
    for row in rows:
        cells = " | ".join(f"{row[name]:.1f}" for name in names)
        lines.append(
            f"| {row['run']} | {row['code']} {row['commit']} | {row['cache']} | {row['wall_seconds']:.1f} | "
            f"{row['wall_seconds'] / row.get('frames', 1):.1f} | {cells} | {row['load_average']:.1f} |"
        )
    if args.baseline:
        warm = [row for row in rows if row["cache"] == "warm"]

        def median(code, name):
            return statistics.median(row[name] for row in warm if row["code"] == code)

        def ratio(name):
            base = median("baseline", name)
            return f"{median('this', name) / base:.2f}" if base >= 0.05 else "-"

        cells = " | ".join(ratio(name) for name in names)
        lines.append(f"| ratio of warm medians | this / baseline | | {ratio('wall_seconds')} | | {cells} | |")
    command = f"python experiments/profile_default.py --runs {args.runs}{' --cold' if args.cold else ''}"
    command += f" --sequence {args.sequence}" if args.sequence else ""
    lines += ["", f"`{command}{' --baseline DIR' if args.baseline else ''}`", ""]
    (out / "table.md").write_text("\n".join(lines))
    print((out / "table.md").read_text())


def write_sequence(folder: Path, count: int) -> Path:
    """The first ``count`` frames from frame 60 of the held-out smoke simulation, with their velocities, as
    ``frameNNNN.npz`` files in ``folder`` (the simulation is cached under ``data/heldout``)."""
    import numpy as np

    from mistyle.data.heldout import held_out_sequence

    densities, velocities = held_out_sequence(60, count, REPO / "data" / "heldout")
    folder.mkdir(parents=True, exist_ok=True)
    for index, (density, velocity) in enumerate(zip(densities, velocities)):
        np.savez(folder / f"frame{index:04d}.npz", density=density, velocity=velocity)
    return folder


if __name__ == "__main__":
    main()
