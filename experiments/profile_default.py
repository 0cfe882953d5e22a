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


def git_commit(checkout: Path) -> str:
    done = subprocess.run(
        ["git", "-C", str(checkout), "rev-parse", "--short=12", "HEAD"], capture_output=True, text=True
    )
    changed = subprocess.run(
        ["git", "-C", str(checkout), "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True
    )
    return (done.stdout.strip() or "unknown") + ("+changes" if changed.stdout.strip() else "")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="results/profile_default")
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--cold", action="store_true", help="the first run with an empty Dr.Jit kernel cache")
    parser.add_argument("--baseline", type=Path, default=None, help="another checkout, run before each run of this one")
    parser.add_argument("extra", nargs="*", help="more mistyle-render options, after --")
    args = parser.parse_args()

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    checkouts = ([("baseline", args.baseline.resolve())] if args.baseline else []) + [("this", REPO)]
    with tempfile.TemporaryDirectory() as scratch:
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
                    "examples/smoke_64.vol",
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
                    "commit": git_commit(checkout),
                    "cache": "cold" if cold else "warm",
                    "wall_seconds": wall,
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
    names = ["start-up"] + [name for name, _ in STAGES] + ["other"]
    lines = [
        "The default output of one 64^3 frame (`mistyle-render --density examples/smoke_64.vol --style "
        f"examples/style_marble.png{' ' + ' '.join(args.extra) if args.extra else ''}`), seconds from process "
        f"start to files written; {os.cpu_count()} cores, load average (1 min) per run as given.",
        "",
        "| run | code | Dr.Jit kernels | total | " + " | ".join(names) + " | load |",
        "|---|---|---|---|" + "---|" * len(names) + "---|",
    ]
    for row in rows:
        cells = " | ".join(f"{row[name]:.1f}" for name in names)
        lines.append(
            f"| {row['run']} | {row['code']} {row['commit']} | {row['cache']} | {row['wall_seconds']:.1f} | {cells} "
            f"| {row['load_average']:.1f} |"
        )
    if args.baseline:
        warm = [row for row in rows if row["cache"] == "warm"]

        def median(code, name):
            return statistics.median(row[name] for row in warm if row["code"] == code)

        ratios = " | ".join(
            f"{median('this', name) / max(median('baseline', name), 1e-9):.2f}" for name in ["wall_seconds"] + names
        )
        lines.append(f"| ratio of warm medians | this / baseline | | {ratios} | |")
    command = f"python experiments/profile_default.py --runs {args.runs}{' --cold' if args.cold else ''}"
    lines += ["", f"`{command}{' --baseline DIR' if args.baseline else ''}`", ""]
    (out / "table.md").write_text("\n".join(lines))
    print((out / "table.md").read_text())


if __name__ == "__main__":
    main()
