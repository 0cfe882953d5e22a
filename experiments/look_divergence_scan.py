"""Which of the benchmark's pairs does the default look's fit diverge on? (#48)

The gradient term of the look's objective (``LookSettings.structure_weight``) drove a few fits to
diverge: on the held-out dense cloud with the mossy-rock texture the loss rose from 0.46 at the start to
0.65-0.93 and stayed there, the head's colours pinned at their bounds (albedo (1, 1, 0.1) before the
colour match, a flat yellow whose only gradients are the silhouette's; hue coverage 0.41 after it).
Since stop 60 a fit that ends above its start keeps its lowest-loss values (``look.diverged``). This
script fits the default look (``Pipeline.fit_look``, as ``mistyle-render`` and the benchmark's
``default`` do; no render) on every pair of the given splits and records whether the fit diverged,
so that only those pairs' benchmark rows need scoring again: elsewhere the output is bit for bit
what it was.

    .venv/bin/python experiments/look_divergence_scan.py      # about 20 min on this 2-core CPU

Writes ``results/look_divergence/scan.jsonl`` (a line per pair; a re-run skips the pairs it has).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

OUT = ROOT / "results" / "look_divergence"
SPLITS = {"heldout": None, "heldout128": None, "real": ["wdas_cloud", "openvdb_smoke", "usd_plume"]}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--splits", default=",".join(SPLITS))
    parser.add_argument("--cache", default="data/heldout", help="where held-out densities are cached")
    args = parser.parse_args(argv)

    from mistyle.benchmark.splits import split_density, split_pairs, split_styles
    from mistyle.files import load_style
    from mistyle.pipeline import Pipeline, PipelineSettings

    pipeline = Pipeline(PipelineSettings())
    path = args.out / "scan.jsonl"
    args.out.mkdir(parents=True, exist_ok=True)
    done = (
        {(r["split"], r["density"], r["style"]) for r in map(json.loads, path.read_text().splitlines())}
        if path.exists()
        else set()
    )
    for split in args.splits.split(","):
        styles = split_styles(split)
        for spec, style_name in split_pairs(split, densities=SPLITS[split]):
            if (split, spec.name, style_name) in done:
                continue
            density = split_density(spec, args.cache)
            losses, notes = [], []
            started = time.perf_counter()
            pipeline.fit_look(
                density,
                load_style(styles[style_name]["path"]),
                notes=notes,
                progress=lambda step, steps, loss: losses.append(loss),
            )
            row = {
                "split": split,
                "density": spec.name,
                "style": style_name,
                "diverged": any("diverged" in note for note in notes),
                "first_loss": losses[0],
                "last_losses_mean": sum(losses[-10:]) / len(losses[-10:]),
                "lowest_loss": min(losses),
                "seconds": time.perf_counter() - started,
            }
            with path.open("a") as stream:
                stream.write(json.dumps(row) + "\n")
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
