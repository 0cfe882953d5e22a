"""What carrying a look's texture with a sequence's velocities costs a frame (``mistyle.advection``).

Per frame after the first: the two fields carried one frame further (one semi-Lagrangian warp of a
coordinate grid each) and the 64-texel texture read through them over the whole grid, at 64^3 and
128^3, random velocities of about a voxel a frame. Written to ``results/mantaflow_flicker/advection_cost.json``.

    .venv/bin/python experiments/bench_advection.py      # about 10 s
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
OUT = ROOT / "results" / "mantaflow_flicker" / "advection_cost.json"


def seconds_per_frame(side: int, frames: int = 12) -> float:
    import torch

    from mistyle.advection import TextureMotion, blend_phases

    shape = (side,) * 3
    rng = np.random.default_rng(0)
    motion = TextureMotion([rng.normal(0, 1, shape + (3,)).astype(np.float32) for _ in range(frames)])
    texture = torch.randn(3, 64, 64, 64, generator=torch.Generator().manual_seed(0))
    started = time.perf_counter()
    for frame in range(1, frames):
        blend_phases(texture, motion.phases(frame), shape)
    return (time.perf_counter() - started) / (frames - 1)


def main() -> None:
    record = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
        "load_1min": os.getloadavg()[0],
        "seconds_per_frame": {f"{side}^3": seconds_per_frame(side) for side in (64, 128)},
    }
    OUT.write_text(json.dumps(record, indent=1) + "\n")
    print(json.dumps(record, indent=1))


if __name__ == "__main__":
    main()
