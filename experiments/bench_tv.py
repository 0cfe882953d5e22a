"""The smoothness term's cost (``objective.losses.tv_loss``): its written-out gradient against autograd's of
the same formula, forward and backward, on a look's albedo crop at 64^3, 128^3 and 256^3 (the crops
``experiments/bench_scale.py``'s smoke has), and that both give the same gradient.

    .venv/bin/python experiments/bench_tv.py          # results/tv_gradient/tv_term.json (about a minute)
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import torch

from mistyle.objective.losses import tv_loss

ROOT = Path(__file__).resolve().parents[1]
CROPS = {64: (56, 60, 58), 128: (110, 120, 116), 256: (220, 240, 232)}


def autograd_tv(volume: torch.Tensor) -> torch.Tensor:
    """``tv_loss``'s formula with autograd's gradient (how it was computed before)."""
    return sum((torch.diff(volume, dim=axis) ** 2).mean() for axis in (2, 3, 4))


def median_seconds(function, volume: torch.Tensor, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        volume.grad = None
        started = time.perf_counter()
        function(volume).backward()
        times.append(time.perf_counter() - started)
    return sorted(times)[len(times) // 2]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--out", type=Path, default=ROOT / "results" / "tv_gradient" / "tv_term.json")
    args = parser.parse_args()
    rows = []
    for side, crop in CROPS.items():
        volume = torch.rand((1, 3, *crop), generator=torch.Generator().manual_seed(side), requires_grad=True)
        before = median_seconds(autograd_tv, volume, args.repeats)
        after = median_seconds(tv_loss, volume, args.repeats)
        (expected,) = torch.autograd.grad(autograd_tv(volume), volume)
        (written,) = torch.autograd.grad(tv_loss(volume), volume)
        relative = float((written - expected).abs().max() / expected.abs().max())
        rows.append(
            {"grid": side, "crop": list(crop), "autograd_ms": before * 1e3, "written_out_ms": after * 1e3,
             "ratio": after / before, "max_relative_gradient_difference": relative}
        )  # fmt: skip
        print(json.dumps(rows[-1]))
    record = {
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}",
        "load_1min_at_end": os.getloadavg()[0],
        "what": "forward + backward of the smoothness term, median of --repeats",
        "rows": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
