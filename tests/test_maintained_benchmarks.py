"""The maintained benchmarks in their quick modes (``make bench-quick``; see experiments/README.md).

``mistyle-bench --quick`` runs in the default suite (``tests/test_benchmark.py``); the performance
benchmark takes minutes even in its quick mode, so it is also marked slow."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.benchmark
@pytest.mark.slow
def test_performance_benchmark_quick():
    """``experiments/bench_all.py --quick``: one JSON line per figure, none an error."""
    result = subprocess.run(
        [sys.executable, str(REPO / "experiments" / "bench_all.py"), "--quick"],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=1800,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    records = [json.loads(line) for line in result.stdout.splitlines() if line.startswith("{")]
    assert not [r for r in records if "error" in r], [r for r in records if "error" in r]
    figures = {r["figure"] for r in records}
    assert {"layer_accuracy", "layer_speed", "skpn_inference", "pathtrace_equal_noise"} <= figures
    assert all("bench_machine" in r for r in records)
