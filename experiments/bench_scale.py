"""Production sizes (#51): the default output's stage times, Dr.Jit kernels and peak memory at 64^3,
128^3 and 256^3, and per frame over a 64^3 sequence; on this CPU always, on CUDA when asked.

Each case runs in a process of its own (``--case``), so its peak memory is its own: the process's peak
resident set (``ru_maxrss``) and, on CUDA, torch's peak allocated memory. A case is what
``mistyle-render`` does by default through ``mistyle.Pipeline``: the network, a look fitted on the frame
(on a sequence: on its key frames, then applied to every frame), one path-traced view per frame at 64 spp
(256^2; 512^2 at 256^3; the preview sequence 64^2 at 4 spp), denoised. Stages are timed as the
pipeline's report times them; the path trace of each frame separately, so a sequence shows what its
first frame costs and what each later one does.
Kernels are Dr.Jit's history (``JitFlag.KernelHistory``) of the path traces: the JIT kernels compiled by
the backend (found neither in the process's cache nor in Dr.Jit's disk cache, which each case starts
empty: a temporary ``HOME``, as a fresh farm worker has). The history is off during the network and the
look, where keeping it costs more than the fit.

Densities: the bundled smoke (``examples/smoke_64.vol``) resampled to each size (trilinear), so every size
holds the same smoke (7% of its box above density 0.01, 41% above zero: the ``occupied`` column); the
sequence is that smoke moved by one voxel and scaled each frame (a new grid every frame); ``sparse256``
is the smoke resampled into a fifth of a 256^3 box, in its low corner, the rest empty (what a frame
costs when the smoke fills a fifth of the domain, against ``frame256``). Style: the demo's (Hokusai's
Great Wave).

    .venv/bin/python experiments/bench_scale.py                    # results/bench_scale/ (~15 min on 2 cores)
    .venv/bin/python experiments/bench_scale.py --device cuda      # the GPU rows, same folder
    bash scripts/gpu_bench.sh                                      # the same on a lent GPU (../shared/gpu/)
    .venv/bin/python experiments/bench_scale.py --quick            # 32^3 and a 3-frame sequence, in seconds

Writes ``rows.jsonl`` (one row per case and device, replaced when run again) and ``table.md``; with
``--label L --append`` (one code's name; the rows of codes run in turn kept), ``repeats.md`` instead:
each code's median and its ratio to the first code's. With
``--before ROWS`` (an earlier commit's rows, e.g. from a worktree of it run in the same session),
``compare.md``: each stage's time and the peak memory as ratios to those rows.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "bench_scale"
STYLE = ROOT / "mistyle" / "data" / "heldout_styles" / "hokusai_great_wave.jpg"
CASES = {
    "frame64": (64, 1),
    "frame128": (128, 1),
    "frame256": (256, 1),
    "sparse256": (256, 1),
    "sequence64": (64, 24),
    "sequence64_preview": (64, 24),
}
RENDERS = {"sequence64_preview": (64, 4)}
"""Cases rendered otherwise than at 256^2 (512^2 from 256^3 on) and 64 spp: ``(side, spp)``. The preview
sequence is the issue's own measure of recompilation on this CPU (64^2 at 4 spp), where a frame's
tracing is short enough for its compilation to show."""
QUICK_CASES = {"frame32": (32, 1), "sequence32": (32, 3)}
SPARSE_FILL = 0.2
"""The share of the box the smoke's own box takes in the sparse case: a fifth, in one corner."""


def density(side: int, frame: int = 0, fill: float = 1.0):
    """The bundled smoke at ``side``^3, moved by ``frame`` voxels along x and scaled (frame ``frame``); with
    ``fill`` below 1, resampled to a box of that share of the grid's, in the grid's low corner."""
    import numpy as np
    import torch
    import torch.nn.functional as F

    from mistyle.files import read_vol

    grid = read_vol(ROOT / "examples" / "smoke_64.vol")
    inner = round(side * fill ** (1 / 3))
    if inner != grid.shape[0]:
        grid = F.interpolate(torch.from_numpy(grid)[None, None], size=(inner,) * 3, mode="trilinear")[0, 0].numpy()
    if inner != side:
        grid = np.pad(grid, [(0, side - inner)] * 3)
    return np.ascontiguousarray(np.roll(grid, frame, axis=2) * (1.0 + 0.02 * frame), dtype=np.float32)


def run_case(name: str, side: int, frames: int, device: str, denoise: str = "oidn") -> dict:
    """One case in this process: the row of its stage times, kernels and peak memory."""
    import resource

    import drjit as dr
    import numpy as np

    from mistyle.pipeline import Pipeline, PipelineSettings, RenderSettings

    res, spp = RENDERS.get(name, (512 if side >= 256 else 256, 64))
    pipeline = Pipeline(PipelineSettings(device=device, render=RenderSettings(res=res, spp=spp, denoise=denoise)))
    fill = SPARSE_FILL if name.startswith("sparse") else 1.0
    grids = [density(side, frame, fill) for frame in range(frames)]
    stacked = np.stack(grids) if frames > 1 else grids[0]
    started = time.perf_counter()
    stylized = pipeline.stylize(stacked, str(STYLE))
    stylize_total = time.perf_counter() - started
    # Kernel history only around the path traces: kept during a look's fit, it costs more than the fit.
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    views = pipeline.views()[:1]
    traced = []
    for frame in range(frames):
        begin = time.perf_counter()
        one = pipeline.frames(grids[frame : frame + 1]) if frames > 1 else stylized.frames
        pipeline.path_trace(one, [stylized.albedos[frame]], views)
        kernels = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
        traced.append(
            {
                "seconds": time.perf_counter() - begin,
                "kernels": len(kernels),
                "compiled": sum(1 for k in kernels if not k["cache_hit"] and not k["cache_disk"]),
            }
        )
    # A look's application to the next frame (a sequence's per-frame cost after the fit): the frame moved by
    # a voxel, so nothing of the fitted frame is reused.
    look_apply = None
    if frames == 1 and stylized.look is not None:
        begin = time.perf_counter()
        stylized.look.stylize(density(side, 1, fill))
        look_apply = time.perf_counter() - begin
    report = stylized.report
    row = {
        "case": name,
        "side": side,
        "frames": frames,
        "device": device,
        "occupied": float(np.mean(grids[0] > 0)),
        "network_seconds": report.get("stylize_seconds"),
        "look_seconds": report.get("look_seconds"),
        "look_apply_seconds": look_apply,
        "stylize_total_seconds": stylize_total,
        "render": f"{res}^2, {spp} spp, " + ("OIDN" if denoise == "oidn" else "not denoised"),
        "path_trace_first_seconds": traced[0]["seconds"],
        "path_trace_later_seconds": (float(np.median([t["seconds"] for t in traced[1:]])) if frames > 1 else None),
        "path_trace_kernels_compiled": [t["compiled"] for t in traced],
        "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
    }
    if device == "cuda":
        import torch

        row["peak_cuda_gb"] = torch.cuda.max_memory_allocated() / 2**30
    row["total_seconds"] = stylize_total + sum(t["seconds"] for t in traced)
    return row


def machine() -> dict:
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    return {"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(), "load_1min": load}


def table(rows: list[dict]) -> str:
    head = (
        "| case | device | network s | look s | path trace s (first / later frames) | kernels compiled per frame "
        "(path trace) | total s | peak RSS GB | occupied |\n|---|---|---|---|---|---|---|---|---|\n"
    )

    def shown(value, digits=2):
        return "-" if value is None else f"{value:.{digits}f}"

    lines = []
    for row in rows:
        later = row["path_trace_later_seconds"]
        compiled = row["path_trace_kernels_compiled"]
        kernels = f"{compiled[0]}" + (f", then {max(compiled[1:])} at most" if len(compiled) > 1 else "")
        lines.append(
            f"| {row['case']} ({row['side']}^3 x {row['frames']}) | {row['device']} | "
            f"{shown(row['network_seconds'])} | "
            f"{shown(row['look_seconds'])} | {shown(row['path_trace_first_seconds'])} / {shown(later)} | {kernels} | "
            f"{shown(row['total_seconds'], 1)} | {shown(row['peak_rss_gb'])} | {row['occupied']:.3f} |"
        )
    return head + "\n".join(lines) + "\n"


def repeats(rows: list[dict]) -> str:
    """Rows of codes run alternately (``--label``, ``--append``): per case, each code's median of each
    stage over its runs, and that median as a ratio to the first code's (the code before)."""
    import statistics

    stages = (
        ("network_seconds", "network s"),
        ("look_seconds", "look s"),
        ("look_apply_seconds", "look applied s"),
        ("path_trace_first_seconds", "path trace s"),
        ("total_seconds", "total s"),
        ("peak_rss_gb", "peak RSS GB"),
    )
    lines = [
        "Codes run one after the other, in turn, in one session: per case and code, the median of its runs, and "
        "that median / the first code's (lower is faster or smaller); the runs' values in brackets.",
        "",
        "| case | code | runs | " + " | ".join(name for _, name in stages) + " |",
        "|---|---|---|" + "---|" * len(stages),
    ]
    for case in dict.fromkeys(row["case"] for row in rows):
        codes = {}
        for row in rows:
            if row["case"] == case:
                codes.setdefault(row.get("code", "-"), []).append(row)
        first = None
        for code, runs in codes.items():
            measured = [key for key, _ in stages if all(run.get(key) is not None for run in runs)]
            medians = {key: statistics.median(run[key] for run in runs) for key in measured}
            first = first or medians
            cells = []
            for key, _ in stages:
                if key not in medians:  # not measured by this code's runs
                    cells.append("-")
                    continue
                ratio = "" if medians is first or key not in first else f" ({medians[key] / first[key]:.2f}x)"
                cells.append(f"{medians[key]:.2f}{ratio} [{', '.join(f'{run[key]:.2f}' for run in runs)}]")
            lines.append(f"| {case} | {code} | {len(runs)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def comparison(rows: list[dict], before: list[dict], label: str) -> str:
    """``rows`` against the same cases of ``before`` (an earlier commit's rows, run in the same session):
    each stage's time as a ratio (lower is faster) and peak memory."""
    stages = (
        ("network_seconds", "network"),
        ("look_seconds", "look"),
        ("path_trace_first_seconds", "path trace, first frame"),
        ("path_trace_later_seconds", "path trace, later frames"),
        ("total_seconds", "total"),
        ("peak_rss_gb", "peak RSS"),
    )
    earlier = {(row["case"], row["device"]): row for row in before}
    lines = [
        f"Against {label}: this folder's row / the earlier row (lower is faster or smaller).",
        "",
        "| case | device | " + " | ".join(name for _, name in stages) + " |",
        "|---|---|" + "---|" * len(stages),
    ]
    for row in rows:
        old = earlier.get((row["case"], row["device"]))
        if old is None:
            continue
        cells = []
        for key, _ in stages:
            new_value, old_value = row.get(key), old.get(key)
            cells.append("-" if not new_value or not old_value else f"{new_value / old_value:.2f}x")
        lines.append(f"| {row['case']} | {row['device']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu", choices=("cpu", "cuda"))
    parser.add_argument("--cases", default="", help="comma-separated cases (default: all)")
    parser.add_argument("--denoise", default="oidn", choices=("oidn", "none"), help="none where OIDN is missing")
    parser.add_argument("--quick", action="store_true", help="32^3 and a 3-frame sequence (a check, not figures)")
    parser.add_argument("--out", default=str(OUT))
    parser.add_argument(
        "--before", help="rows.jsonl of an earlier commit's run (same session): compare.md gives the ratios"
    )
    parser.add_argument("--before-label", default="the earlier rows", help="what --before is, for compare.md")
    parser.add_argument("--label", help="the code's name in each row (for --append runs of several codes)")
    parser.add_argument(
        "--append",
        action="store_true",
        help="keep the case's earlier rows (runs of codes in turn; repeats.md gives their medians)",
    )
    parser.add_argument("--case", help=argparse.SUPPRESS)  # run one case in this process, print its row
    args = parser.parse_args(argv)
    cases = QUICK_CASES if args.quick else CASES
    if args.case:
        side, frames = {**CASES, **QUICK_CASES}[args.case]
        print(json.dumps(run_case(args.case, side, frames, args.device, args.denoise)))
        return
    chosen = [name for name in (args.cases.split(",") if args.cases else cases) if name]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows_path = out / "rows.jsonl"
    rows = [json.loads(line) for line in rows_path.read_text().splitlines()] if rows_path.exists() else []
    for name in chosen:
        before = machine()
        with tempfile.TemporaryDirectory(prefix="bench-scale-home-") as home:  # Dr.Jit's disk cache starts empty
            result = subprocess.run(
                [sys.executable, __file__, "--case", name, "--device", args.device, "--denoise", args.denoise],
                capture_output=True,
                text=True,
                cwd=ROOT,
                env={**os.environ, "HOME": home},
            )
        if result.returncode != 0:
            raise SystemExit(f"case {name} failed:\n{result.stderr[-3000:]}")
        row = {**json.loads(result.stdout.strip().splitlines()[-1]), **before}
        if args.label:
            row["code"] = args.label
        print(json.dumps(row), flush=True)
        if not args.append:
            rows = [r for r in rows if (r["case"], r["device"]) != (name, args.device)]
        rows_path.write_text("".join(json.dumps(r) + "\n" for r in rows + [row]))
        rows.append(row)
    if any("code" in row for row in rows):
        (out / "repeats.md").write_text(repeats(rows))
    else:
        (out / "table.md").write_text(table(rows))
    if args.before:
        before = [json.loads(line) for line in Path(args.before).read_text().splitlines() if line.strip()]
        (out / "compare.md").write_text(comparison(rows, before, args.before_label))


if __name__ == "__main__":
    main()
