"""Where a training step's time goes (issue: style fidelity II asks for this before speeding it up).

Builds the trainer of ``--config`` (generating its dataset on first use), takes ``--warmup`` steps,
then profiles ``--steps`` steps with cProfile and reports the seconds per step spent in each part:
data loading, the style extractor, the SKPN forward pass, Ls preparation, the layer's forward render,
the style objective, the layer's adjoint (inside backward), the rest of backward (SKPN, extractor),
and the optimizer: inclusive times, so the layer adjoint is part of backward (all).

    python experiments/profile_train_step.py --config configs/cpu.toml          # 3 + 10 steps
    python experiments/profile_train_step.py --config configs/tiny.toml --quick
"""

from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import tempfile
import time
from pathlib import Path

PARTS = {  # part -> (file suffix, function name) of the profiled function, inclusive time
    "data (sample_batch)": ("train/trainer.py", "sample_batch"),
    "style encoder": ("train/trainer.py", "_style_inputs"),
    "SKPN forward": ("model/skpn.py", "forward"),
    "Ls preparation": ("integrators/prepared.py", "prepare_density"),
    "layer forward": ("bridge_torch.py", "render_views"),
    "objective": ("objective/style.py", "loss"),
    "layer adjoint": ("bridge_torch.py", "backward"),
    "backward (all)": ("torch/_tensor.py", "backward"),
    "optimizer": ("torch/optim/adam.py", "step"),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", default="configs/cpu.toml")
    parser.add_argument("--set", action="append", default=[], dest="overrides")
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--warmup", type=int, default=3)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    if args.quick:
        args.steps, args.warmup = 2, 1

    from mistyle.model.config import load_config
    from mistyle.train.trainer import Trainer

    config = load_config(Path(args.config), args.overrides)
    trainer = Trainer(config, Path(tempfile.mkdtemp()) / "profile", log=lambda *a, **k: None)
    for _ in range(args.warmup):
        trainer.train_step()
    profile = cProfile.Profile()
    started = time.perf_counter()
    profile.enable()
    for _ in range(args.steps):
        trainer.train_step()
    profile.disable()
    per_step = (time.perf_counter() - started) / args.steps
    stats = pstats.Stats(profile).stats  # (file, line, name) -> (calls, prim calls, tottime, cumtime, callers)
    parts = {}
    for part, (suffix, name) in PARTS.items():
        # The outermost of same-named functions (an SKPN forward contains its blocks' forwards).
        parts[part] = (
            max(
                [
                    value[3]
                    for (file, _, function), value in stats.items()
                    if function == name and file.replace("\\", "/").endswith(suffix)
                ],
                default=0.0,
            )
            / args.steps
        )
    print(
        json.dumps(
            {
                "config": args.config,
                "overrides": args.overrides,
                "seconds_per_step": round(per_step, 3),
                **{part: round(seconds, 3) for part, seconds in parts.items()},
            }
        )
    )


if __name__ == "__main__":
    main()
