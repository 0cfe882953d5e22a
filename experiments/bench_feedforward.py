"""Seconds per volume of the feed-forward path (``render_final --refine 0``): the network alone, and the
network followed by the colour match (``mistyle.colour_match``), in one process, the same way.

For each density, after one warm-up call of each, ``--repeats`` alternating calls of
``Stylizer(density, style, match_colours=False)`` and ``match_colours=True`` (the style's kernels are
predicted inside every call, as users get them); the medians, their difference (the colour match's
cost) and the load average before and after are printed as one JSON line per density.

    python experiments/bench_feedforward.py                  # smoke64, the bundled smoke_64.vol, smoke128; 5 repeats
    python experiments/bench_feedforward.py --repeats 2
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STYLE = ROOT / "mistyle" / "data" / "heldout_styles" / "hokusai_great_wave.jpg"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--cache", default="data/heldout", help="where held-out densities are cached")
    args = parser.parse_args()

    from mistyle.api import Stylizer
    from mistyle.data.heldout import HELD_OUT_DENSITIES, held_out_density
    from mistyle.files import load_density, load_style

    stylizer = Stylizer()
    style = load_style(STYLE)
    specs = {spec.name: spec for spec in HELD_OUT_DENSITIES}
    densities = {
        "smoke64": held_out_density(specs["smoke64"], args.cache),
        "examples/smoke_64.vol": load_density(ROOT / "examples" / "smoke_64.vol"),
        "smoke128": held_out_density(specs["smoke128"], args.cache),
    }
    for name, density in densities.items():
        load_before = os.getloadavg()[0]
        times = {False: [], True: []}
        for match in (False, True):
            stylizer(density, style, match_colours=match)  # warm-up: Mitsuba's kernels, torch's allocator
        for _ in range(args.repeats):
            for match in (False, True):
                started = time.perf_counter()
                stylizer(density, style, match_colours=match)
                times[match].append(time.perf_counter() - started)
        network, matched = statistics.median(times[False]), statistics.median(times[True])
        print(
            json.dumps(
                {
                    "density": name,
                    "shape": list(density.shape),
                    "network_seconds": round(network, 3),
                    "with_colour_match_seconds": round(matched, 3),
                    "colour_match_seconds": round(matched - network, 3),
                    "repeats": args.repeats,
                    "cpus": os.cpu_count(),
                    "load_before": load_before,
                    "load_after": os.getloadavg()[0],
                }
            ),
            flush=True,
        )


if __name__ == "__main__":
    main()
