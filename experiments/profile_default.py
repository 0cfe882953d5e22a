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

Writes ``rows.jsonl`` and ``table.md`` under ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
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


def timed(command: list[str], env: dict) -> float:
    started = time.perf_counter()
    subprocess.run(command, check=True, cwd=REPO, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="results/profile_default")
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--cold", action="store_true", help="the first run with an empty Dr.Jit kernel cache")
    parser.add_argument("extra", nargs="*", help="more mistyle-render options, after --")
    args = parser.parse_args()

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        for run in range(args.runs):
            env = dict(os.environ)
            cold = args.cold and run == 0
            if cold:  # Dr.Jit keeps its kernel cache under $HOME/.drjit
                home = Path(scratch) / "home"
                shutil.rmtree(home, ignore_errors=True)
                home.mkdir()
                env["HOME"] = str(home)
            target = Path(scratch) / f"run{run}"
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
            wall = timed(command, env)
            imports = timed([sys.executable, "-c", IMPORTS], env)
            report = json.loads((target / "report.json").read_text())
            row = {"run": run, "cache": "cold" if cold else "warm", "wall_seconds": wall, "start-up": imports}
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
        "| run | Dr.Jit kernels | total | " + " | ".join(names) + " | load |",
        "|---|---|---|" + "---|" * len(names) + "---|",
    ]
    for row in rows:
        cells = " | ".join(f"{row[name]:.1f}" for name in names)
        lines.append(
            f"| {row['run']} | {row['cache']} | {row['wall_seconds']:.1f} | {cells} | {row['load_average']:.1f} |"
        )
    lines += ["", f"`python experiments/profile_default.py --runs {args.runs}{' --cold' if args.cold else ''}`", ""]
    (out / "table.md").write_text("\n".join(lines))
    print((out / "table.md").read_text())


if __name__ == "__main__":
    main()
