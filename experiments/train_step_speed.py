"""Training-step time, before and after a change, in one run (issue: style fidelity II asks for >= 1.5x).

Each arm is a code revision (a git commit checked out into a temporary worktree, or the working
tree) with ``--set`` overrides. Arms run in turns, each in its own process (so every arm pays the
same start-up and sees the same machine load), for ``--rounds`` rounds; one round times ``--steps``
training steps after ``--warmup``. Prints one JSON line per (round, arm) and a summary with the
median seconds per step of each arm and its speed-up over the first arm.

    python experiments/train_step_speed.py --config configs/cpu.toml \\
        --arm before=9508e9d --arm after=: --arm after-bf16=:run.precision=bf16
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def worker(args) -> None:
    import mistyle
    from mistyle.model.config import load_config
    from mistyle.train.trainer import Trainer

    config = load_config(Path(args.config), args.overrides)
    trainer = Trainer(config, Path(tempfile.mkdtemp()) / "speed", log=lambda *a, **k: None)
    for _ in range(args.warmup):
        trainer.train_step()
    started = time.perf_counter()
    for _ in range(args.steps):
        trainer.train_step()
    print(
        json.dumps(
            {
                "seconds_per_step": (time.perf_counter() - started) / args.steps,
                "mistyle": str(Path(mistyle.__file__).parent.parent),
            }
        )
    )


def parse_arm(text: str) -> tuple[str, str, list[str]]:
    """``name=REVISION[:key=value[,key=value]]``; an empty revision is the working tree."""
    name, _, rest = text.partition("=")
    revision, _, overrides = rest.partition(":")
    return name, revision, [o for o in overrides.split(",") if o]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", default="configs/cpu.toml")
    parser.add_argument(
        "--arm", action="append", default=[], help="name=REVISION[:key=value,...] (REVISION empty: this tree)"
    )
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--warmup", type=int, default=3)
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--set", action="append", default=[], dest="overrides", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        return worker(args)
    arms = [parse_arm(text) for text in args.arm or ["this=:"]]
    trees = {}
    with tempfile.TemporaryDirectory() as scratch:
        for _, revision, _ in arms:
            if revision and revision not in trees:
                tree = Path(scratch) / revision
                subprocess.run(
                    ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), revision],
                    check=True,
                    capture_output=True,
                )
                trees[revision] = tree
        config = str((ROOT / args.config).resolve())
        seconds = {name: [] for name, _, _ in arms}
        try:
            for round_index in range(args.rounds):
                for name, revision, overrides in arms:
                    tree = trees.get(revision, ROOT)
                    command = [
                        sys.executable,
                        str(Path(__file__).resolve()),
                        "--worker",
                        "--config",
                        config,
                        "--steps",
                        str(args.steps),
                        "--warmup",
                        str(args.warmup),
                    ]
                    command += [item for override in overrides for item in ("--set", override)]
                    env = dict(os.environ, PYTHONPATH=str(tree))
                    result = subprocess.run(command, cwd=ROOT, env=env, check=True, capture_output=True, text=True)
                    record = json.loads(result.stdout.strip().splitlines()[-1])
                    if Path(record.pop("mistyle")).resolve() != tree.resolve():  # the arm ran the code it names
                        raise SystemExit(f"arm {name}: imported mistyle from elsewhere than {tree}")
                    seconds[name].append(record["seconds_per_step"])
                    print(
                        json.dumps(
                            {
                                "round": round_index,
                                "arm": name,
                                "revision": revision or "working tree",
                                "overrides": overrides,
                                **record,
                            }
                        ),
                        flush=True,
                    )
        finally:
            for tree in trees.values():
                subprocess.run(
                    ["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], capture_output=True
                )
    first = statistics.median(seconds[arms[0][0]])
    summary = {
        name: {
            "median_seconds_per_step": round(statistics.median(values), 3),
            "speedup": round(first / statistics.median(values), 2),
        }
        for name, values in seconds.items()
    }
    print(
        json.dumps(
            {
                "config": args.config,
                "steps": args.steps,
                "rounds": args.rounds,
                "load": os.getloadavg()[0],
                "summary": summary,
            }
        )
    )


if __name__ == "__main__":
    main()
