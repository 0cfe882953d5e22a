"""SKPN parameter counts and feed-forward (inference) times for the tiny, CPU and paper widths.

One process, one run: every (config, grid size) pair is timed the same way, as the median of
``--repeats`` forward passes under ``torch.no_grad()`` (batch 1, the style's features computed
once, outside the timing), after one warm-up pass. Peak resident memory is reported per process.
The paper's figures (2080Ti GPU) are 0.04 s at 64^3, 0.25 s at 128^3 and 0.51 s at 128x256x128.

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

import torch

PAPER_SECONDS = {(64, 64, 64): 0.04, (128, 128, 128): 0.25, (128, 256, 128): 0.51}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--configs", nargs="+", default=["tiny", "cpu", "paper"])
    args = parser.parse_args()
    sizes = [(32, 32, 32), (64, 64, 64)] if args.quick else [(64, 64, 64), (128, 128, 128), (128, 256, 128)]

    from mistyle.data.procedural import pyroclastic_sphere
    from mistyle.model.config import load_config
    from mistyle.model.features import make_extractor
    from mistyle.model.skpn import SKPN, parameter_count

    extractor = make_extractor("filterbank")
    style_levels = list(extractor(torch.rand(1, 3, 128, 128)))
    print(json.dumps({"machine": f"{os.cpu_count()} CPUs", "torch_threads": torch.get_num_threads(),
                      "load_average": os.getloadavg(), "extractor": extractor.name}))
    for name in args.configs:
        config = load_config(f"configs/{name}.toml")
        config.model.style_channels = extractor.channels
        model = SKPN(config.model).eval()
        vgg_config = load_config(f"configs/{name}.toml").model
        vgg_config.style_channels = (64, 128, 256, 512)
        parameters_vgg16 = parameter_count(SKPN(vgg_config))
        for size in sizes:
            density = torch.from_numpy(pyroclastic_sphere(size, radius=0.35, seed=1))[None, None]
            with torch.no_grad():
                model(density, style_levels)
                times = []
                for _ in range(args.repeats):
                    started = time.perf_counter()
                    model(density, style_levels)
                    times.append(time.perf_counter() - started)
            print(json.dumps({"config": name, "widths": list(config.model.widths), "parameters": parameter_count(model),
                              "parameters_with_vgg16_styles": parameters_vgg16,
                              "size": list(size), "seconds": statistics.median(times),
                              "paper_gpu_seconds": PAPER_SECONDS.get(size),
                              "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}), flush=True)


if __name__ == "__main__":
    main()
