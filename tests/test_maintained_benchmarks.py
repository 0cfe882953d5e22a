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


@pytest.mark.benchmark
@pytest.mark.slow
def test_scale_benchmark_quick(tmp_path):
    """``experiments/bench_scale.py --quick``: a row per case with its stages, kernels and peak memory."""
    result = subprocess.run(
        [sys.executable, str(REPO / "experiments" / "bench_scale.py"), "--quick", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=1800,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    rows = [json.loads(line) for line in (tmp_path / "rows.jsonl").read_text().splitlines()]
    assert [row["case"] for row in rows] == ["frame32", "sequence32"]
    for row in rows:
        assert (
            row["look_seconds"] > 0
            and row["peak_rss_gb"] > 0
            and len(row["path_trace_kernels_compiled"]) == row["frames"]
        )
    assert "| sequence32 (32^3 x 3) | cpu |" in (tmp_path / "table.md").read_text()


def test_scale_benchmark_repeats_give_each_codes_median_and_its_ratio_to_the_first():
    """``bench_scale.py --label L --append``: runs of two codes in turn, summarised per code."""
    sys.path.insert(0, str(REPO / "experiments"))
    try:
        from bench_scale import repeats
    finally:
        sys.path.remove(str(REPO / "experiments"))
    stages = ("network_seconds", "look_seconds", "look_apply_seconds", "path_trace_first_seconds", "total_seconds")

    def row(code, seconds):
        return {"case": "frame128", "code": code, **dict.fromkeys(stages, seconds)}

    rows = [row("before", 8.0), row("after", 4.0), row("before", 6.0), row("after", 5.0), row("before", 7.0)]
    rows[0]["peak_rss_gb"] = 2.0  # measured by one run only: no median
    lines = [line for line in repeats(rows).splitlines() if line.startswith("| frame128")]
    assert lines[0].startswith("| frame128 | before | 3 | 7.00 [8.00, 6.00, 7.00] |")
    assert lines[1].startswith("| frame128 | after | 2 | 4.50 (0.64x) [4.00, 5.00] |")
    assert lines[0].endswith("| 7.00 [8.00, 6.00, 7.00] | - |") and lines[1].endswith("| - |")


@pytest.mark.benchmark
@pytest.mark.slow
def test_memory_trace_quick(tmp_path):
    """``experiments/memory_trace.py --side 32``: a finished row whose stages each have a time and a peak."""
    result = subprocess.run(
        [sys.executable, str(REPO / "experiments" / "memory_trace.py"), "--side", "32", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=900,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    (row,) = [json.loads(line) for line in (tmp_path / "rows.jsonl").read_text().splitlines()]
    assert row["finished"] and row["stopped"] is None and row["peak_gb"] > 0
    stages = {stage["stage"] for stage in row["stages"]}
    assert {"network forward", "colour match fit", "look fit steps", "path trace"} <= stages
    assert all(stage["seconds"] >= 0 for stage in row["stages"])
