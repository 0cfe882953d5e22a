"""SKPN parameter counts and feed-forward (inference) times for the tiny, CPU and paper widths.

One process, one run: for every (config, grid size) pair, the plain path (``SKPN.forward`` in
float32 over the whole box) and the fast path that inference uses (``SKPN.infer``: bfloat16
autocast, the box cropped to the density's bounding box plus a margin) are timed the same way, as
the median of ``--repeats`` passes under ``torch.no_grad()`` (batch 1, the style's kernels
predicted once, outside the timing), after one warm-up pass, and their albedos compared on the
voxels that hold density (``max_abs_change``, ``mean_abs_change``). Peak resident memory is the
process's (sizes run from small to large): ``peak_rss_gb_after_fast`` is read after the fast path
and before the plain path of the same size, so at the largest size it bounds the fast path's.
The paper's figures (2080Ti GPU) are 0.04 s at 64^3, 0.25 s at 128^3 and 0.51 s at 128x256x128.

``--configs shipped`` times the bundled, trained network (its albedo changes are the ones users
see; the other configs have random weights).

    python experiments/bench_skpn.py                    # 64^3, 128^3, 128x256x128
    python experiments/bench_skpn.py --quick            # 32^3 and 64^3 only
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import time
from pathlib import Path

import torch

STYLE = Path(__file__).resolve().parents[1] / "mistyle" / "data" / "heldout_styles" / "hokusai_great_wave.jpg"
PAPER_SECONDS = {(64, 64, 64): 0.04, (128, 128, 128): 0.25, (128, 256, 128): 0.51}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--configs",
        nargs="+",
        default=["shipped", "paper"],
        help="configs/NAME.toml with random weights, or 'shipped' (the bundled network)",
    )
    args = parser.parse_args()
    sizes = [(32, 32, 32), (64, 64, 64)] if args.quick else [(64, 64, 64), (128, 128, 128), (128, 256, 128)]

    for record in run(sizes, args.configs, args.repeats):
        print(json.dumps(record), flush=True)


def median_seconds(repeats: int, fn) -> tuple[float, torch.Tensor]:
    fn()
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - started)
    return statistics.median(times), result


def run(sizes, configs, repeats: int = 3) -> list[dict]:
    """One record per (config, size): plain and fast seconds, their ratio and the albedo change."""
    from mistyle.data.procedural import pyroclastic_sphere
    from mistyle.model.config import load_config
    from mistyle.model.features import make_extractor
    from mistyle.model.skpn import SKPN, parameter_count

    records = []
    for name in configs:
        if name == "shipped":
            from mistyle.api import Stylizer

            stylizer = Stylizer()
            model, widths = stylizer.trained.model, stylizer.config.model.widths
            kernels = stylizer.kernels(str(STYLE))
            parameters_vgg16 = None
        else:
            extractor = make_extractor("filterbank")
            config = load_config(f"configs/{name}.toml")
            config.model.style_channels = extractor.channels
            model, widths = SKPN(config.model).eval(), config.model.widths
            with torch.no_grad():
                kernels = model.predict_kernels(
                    list(extractor(torch.rand(1, 3, 128, 128, generator=torch.Generator().manual_seed(0))))
                )
            vgg_config = load_config(f"configs/{name}.toml").model
            vgg_config.style_channels = (64, 128, 256, 512)
            parameters_vgg16 = parameter_count(SKPN(vgg_config))
        for size in sizes:
            density = torch.from_numpy(pyroclastic_sphere(size, radius=0.35, seed=1))[None, None]
            with torch.no_grad():  # the fast path first: the peak after it bounds its own memory
                fast_seconds, fast = median_seconds(repeats, lambda: model.infer(density, kernels))
                peak_after_fast = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
                plain_seconds, plain = median_seconds(repeats, lambda: model(density, kernels))
            change = (fast - plain)[0].permute(1, 2, 3, 0)[density[0, 0] > 0].abs()
            records.append(
                {
                    "figure": "skpn_inference",
                    "config": name,
                    "widths": list(widths),
                    "parameters": parameter_count(model),
                    "parameters_with_vgg16_styles": parameters_vgg16,
                    "size": list(size),
                    "occupied_fraction": float((density > 0).float().mean()),
                    "plain_seconds": plain_seconds,
                    "fast_seconds": fast_seconds,
                    "speedup": plain_seconds / fast_seconds,
                    "max_abs_change": float(change.max()),
                    "mean_abs_change": float(change.mean()),
                    "paper_gpu_seconds": PAPER_SECONDS.get(size),
                    "peak_rss_gb_after_fast": peak_after_fast,
                    "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
                    "load_avg_1m": os.getloadavg()[0],
                    "cpu_count": os.cpu_count(),
                    "torch_threads": torch.get_num_threads(),
                }
            )
    return records


if __name__ == "__main__":
    main()
