"""Every performance figure of docs/performance.md, one JSON line each, from one command.

Runs the benchmarks one after another (never two at once, so they do not share the cores), each
timing its fast path against the plain path it replaces in the same process:

* ``layer_accuracy``: the fast layer against the single-scattering path tracer
  (``layer_vs_pathtraced.py``: relative RMSE, layer and path-tracer seconds);
* ``layer_speed``: the layer's forward + backward against the pure-torch layer, and the sheared Ls
  precompute against brute force with the image error it causes, at 64^3 and 128^3
  (``bench_layer.py``);
* ``skpn_inference``: ``SKPN.infer`` (bfloat16, empty space cropped) against the float32 forward
  pass over the whole box, paper widths and the shipped network, at 64^3, 128^3 and 128x256x128
  (``bench_skpn.py``);
* ``pathtrace_equal_noise``: volpath through bricks with their own majorants against one medium,
  time to equal noise on sparse smoke (``bench_pathtrace.py``).

Each line carries the machine's load when it was measured.

    python experiments/bench_all.py            # the figures of docs/performance.md (~25 min here)
    python experiments/bench_all.py --quick    # small sizes, a few minutes
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def benchmarks(quick: bool) -> list[tuple[str, list[str]]]:
    """``(figure, command line)`` of every benchmark, in the order they run."""
    q = ["--quick"] if quick else []
    layer_sizes = [["--quick"]] if quick else [["--res", "64"], ["--res", "128", "--repeats", "2"]]
    return [
        ("layer_accuracy", ["layer_vs_pathtraced.py", *q]),
        *[("layer_speed", ["bench_layer.py", *args]) for args in layer_sizes],
        ("skpn_inference", ["bench_skpn.py", "--configs", "paper", "shipped", "--repeats", "2", *q]),
        ("pathtrace_equal_noise", ["bench_pathtrace.py", *q]),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--only", nargs="+", metavar="FIGURE", help="run only these figures")
    args = parser.parse_args()
    machine = {
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "date": time.strftime("%Y-%m-%d"),
    }
    for figure, command in benchmarks(args.quick):
        if args.only and figure not in args.only:
            continue
        started = time.perf_counter()
        load_before = os.getloadavg()[0]
        result = subprocess.run([sys.executable, str(HERE / command[0]), *command[1:]], capture_output=True, text=True)
        if result.returncode != 0:
            print(
                json.dumps({"figure": figure, "command": command, "error": result.stderr.strip()[-2000:]}), flush=True
            )
            continue
        for line in result.stdout.splitlines():
            if not line.startswith("{"):
                continue
            record = json.loads(line)
            record.setdefault("figure", figure)
            record["command"] = "python experiments/" + " ".join(command)
            record["bench_machine"] = {**machine, "load_avg_1m_before": round(load_before, 2)}
            record["bench_seconds"] = round(time.perf_counter() - started, 1)
            print(json.dumps(record), flush=True)


if __name__ == "__main__":
    main()
