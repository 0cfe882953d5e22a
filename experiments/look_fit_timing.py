"""A look's fit at 64^3: the default (a solid-texture start, its synthesis counted every time, and the
objective's gradient term) against the look without the term and the look of #48's filing (32 texels
from zeros) with the sliced loss by rank and by sorting the projections, in one run (#48's time bound:
a look's fit <= 1.5x the previous look's).

The loss before is kept here as a reference (``sorted_sliced_loss``): it sorts the projected points
with ``torch.sort`` and back-propagates through the sort; today's compares each point with the
target's quantile at its rank (``objective.losses.sliced_wasserstein_loss``), the same value and
gradient (``tests/test_solid_texture.py``). Arms alternate, ``REPEATS`` each, after one warm-up fit.

    .venv/bin/python experiments/look_fit_timing.py     # about 3 min on 2 cores; results/look_fit_timing/
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

OUT = ROOT / "results" / "look_fit_timing"
REPEATS = 3
DENSITY, STYLE = "val_smoke64", "klimt_the_kiss"


def sorted_sliced_loss(points, target, projections=64, generator=None):
    """The sliced loss as it was computed before: sort the points' projections (with gradient)."""
    import torch

    from mistyle.objective.losses import _quantiles, projected_target

    directions, theirs = projected_target(points, target, projections, generator)
    ours = torch.sort(points @ directions, dim=0).values
    with torch.no_grad():
        theirs = _quantiles(theirs, ours.shape[0]).T
    return ((ours - theirs) ** 2).mean() * points.shape[1]


def main() -> None:
    import mistyle.objective.style as style_module
    from mistyle.benchmark.splits import split_density, split_pairs
    from mistyle.data.heldout import VALIDATION_STYLE_DIR
    from mistyle.files import load_style
    from mistyle.look import LookSettings, fit_look
    from mistyle.solid_texture import _cached
    from mistyle.stylizer import Stylizer

    ranked = style_module.sliced_wasserstein_loss
    spec = split_pairs("validation", [DENSITY], [STYLE])[0][0]
    density = split_density(spec)
    style = load_style(VALIDATION_STYLE_DIR / f"{STYLE}.jpg")
    stylizer = Stylizer()
    previous = LookSettings(texture_side=32, texture_start_strength=0.0)
    arms = {
        "previous look, loss by sorting": (sorted_sliced_loss, previous),
        "previous look, loss by rank": (ranked, previous),
        "solid-texture start, no gradient term": (ranked, LookSettings(structure_weight=0.0)),
        "default: solid-texture start, gradient term": (ranked, LookSettings()),
    }
    fit_look(stylizer, [density], style)  # warm-up: imports, kernels
    seconds = {name: [] for name in arms}
    for _ in range(REPEATS):
        for name, (loss, settings) in arms.items():
            style_module.sliced_wasserstein_loss = loss
            _cached.cache_clear()  # the default's synthesis counted in every repeat
            started = time.perf_counter()
            fit_look(stylizer, [density], style, settings=settings)
            seconds[name].append(time.perf_counter() - started)
    style_module.sliced_wasserstein_loss = ranked
    base = min(seconds["previous look, loss by sorting"])
    record = {
        "command": "python experiments/look_fit_timing.py",
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs",
        "load_before": os.getloadavg()[0],
        "pair": [DENSITY, STYLE],
        "seconds": seconds,
        "best_over_previous_look_by_sorting": {name: min(values) / base for name, values in seconds.items()},
    }
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "timings.json").write_text(json.dumps(record, indent=2) + "\n")
    print(json.dumps(record["best_over_previous_look_by_sorting"], indent=2))


if __name__ == "__main__":
    main()
