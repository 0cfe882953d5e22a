"""Time the smoke solver and dataset generation, and project the wall time of whole datasets.

In one run:
  * seconds per solver frame at 64^3 and 128^3 (after a warm-up), and the largest |div u| right
    after the projection;
  * one complete 64^3 plume through ``generate_smoke`` (90 frames simulated, 61-90 kept, Ls cached,
    files written), and one 128^3 plume's cost from a shortened run, each with its bytes on disk;
  * the projected wall time and size of the ``cpu`` dataset (20 plumes at 64^3, 30 frames each)
    and of the ``paper`` dataset (100 x 30 frames at 64^3 + 20 x 30 x 5 crops of 64^3 from 128^3).

Prints one JSON line.

    python experiments/bench_smoke.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import torch


def solver_seconds(resolution: int, frames: int, warmup: int):
    from mistyle.data.smoke import PlumeConfig, SmokeSolver

    solver = SmokeSolver(PlumeConfig(resolution=(resolution,) * 3), seed=0)
    for _ in range(warmup):
        solver.step()
    divergence, start = 0.0, time.perf_counter()
    for _ in range(frames):
        solver._inflow()
        solver._add_forces()
        solver._project()
        divergence = max(divergence, float(solver.divergence().abs().max()))
        solver.cell_velocity()  # what step() records, so the timing matches a real frame
        solver._advect()
    return (time.perf_counter() - start) / frames, divergence


def plume_cost(spec_kwargs: dict):
    from mistyle.data.generate import SmokeDatasetSpec, generate_smoke

    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        generate_smoke(SmokeDatasetSpec(**spec_kwargs), Path(tmp), log=lambda *a: None)
        seconds = time.perf_counter() - start
        files = list(Path(tmp).rglob("*.npz"))
        return seconds, sum(f.stat().st_size for f in files), len(files)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="32^3 and 48^3, short plumes")
    args = parser.parse_args()
    torch.set_flush_denormal(True)
    from mistyle.backend import use_variant

    use_variant("cpu")
    small, large = (32, 48) if args.quick else (64, 128)
    frames, warmup = (5, 5) if args.quick else (10, 20)
    seconds_small, div_small = solver_seconds(small, frames, warmup)
    seconds_large, div_large = solver_seconds(large, frames, warmup)

    full = 90 if not args.quick else 12
    keep = (61, 90) if not args.quick else (9, 12)
    kept = keep[1] - keep[0] + 1
    plume_small, bytes_small, files_small = plume_cost(
        dict(resolution=small, plumes=1, frames=full, keep_first=keep[0], keep_last=keep[1])
    )
    # A large plume: time its simulated frames from the solver figure, and its crops (Ls + write)
    # from a run that keeps 2 frames.
    crop = small
    crops_run, crops_bytes, crops_files = plume_cost(
        dict(resolution=large, plumes=1, frames=2, keep_first=1, keep_last=2, crop=crop, crops_per_frame=5)
    )
    per_crop = (crops_run - 2 * seconds_large) / crops_files
    plume_large = full * seconds_large + kept * 5 * per_crop
    bytes_large = crops_bytes / crops_files * kept * 5

    cpu_plumes, paper_small, paper_large = 20, 100, 20
    result = {
        "solver_seconds_per_frame": {f"{small}^3": seconds_small, f"{large}^3": seconds_large},
        "max_divergence_after_projection": {f"{small}^3": div_small, f"{large}^3": div_large},
        "plume_seconds": {f"{small}^3": plume_small, f"{large}^3_crops_projected": plume_large},
        "plume_bytes": {f"{small}^3": bytes_small, f"{large}^3_crops": bytes_large},
        "files_per_plume": {f"{small}^3": files_small, f"{large}^3_crops": kept * 5},
        "cpu_dataset": {
            "plumes": cpu_plumes,
            "frames": cpu_plumes * kept,
            "hours_projected": cpu_plumes * plume_small / 3600,
            "gigabytes": cpu_plumes * bytes_small / 1e9,
        },
        "paper_dataset": {
            "frames": paper_small * kept + paper_large * kept * 5,
            "hours_projected": (paper_small * plume_small + paper_large * plume_large) / 3600,
            "gigabytes": (paper_small * bytes_small + paper_large * bytes_large) / 1e9,
        },
        "machine": {
            "cpu_count": os.cpu_count(),
            "torch_threads": torch.get_num_threads(),
            "load_avg_1m": os.getloadavg()[0],
        },
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
