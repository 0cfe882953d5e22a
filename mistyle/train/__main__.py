"""``mistyle-train`` (``python -m mistyle.train``): train SKPN through the fast Mitsuba layer, or run the baseline.

    python -m mistyle.train --config configs/cpu.toml --out runs/cpu
    python -m mistyle.train --config configs/cpu.toml --out runs/cpu --resume         # continue from last.pt
    python -m mistyle.train --config configs/cpu.toml --out runs/cpu2 --init mistyle/checkpoints/skpn_cpu.pt
    python -m mistyle.train --config configs/tiny.toml --set optim.steps=50 --out runs/t
    torchrun --nproc_per_node 2 -m mistyle.train --config configs/tiny.toml --out runs/ddp
    python -m mistyle.train --config configs/cpu.toml --optimize --checkpoint runs/cpu/final.pt --out runs/baseline
    python -m mistyle.train --recipe skpn_cpu --out runs/skpn_cpu      # a named recipe: every stage (train.recipes)

``--optimize`` fits albedo grids directly (no network) to held-out styles on held-out densities
with the run's objective and light, and compares them with the network's feed-forward albedo
(``--checkpoint``) in quality (sliced Wasserstein distance on held-out views) and time.

``--out`` is refused before any work when it is a file or holds a file mistyle did not write (the
run folder's manifest, ``mistyle.ownership``), and one run writes it at a time (its lock).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="mistyle-train", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--config", type=Path, help="a TOML file, e.g. configs/cpu.toml")
    source.add_argument("--recipe", help="a named recipe of mistyle.train.recipes (e.g. skpn_cpu): all its stages")
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="SECTION.KEY=VALUE",
        help="override one config value (repeatable), e.g. --set optim.lr=1e-4",
    )
    parser.add_argument("--out", type=Path, required=True, help="run directory (checkpoints, metrics, previews)")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out from its last.pt")
    parser.add_argument(
        "--init",
        type=Path,
        default=None,
        help="start a new run from this checkpoint's weights (training or exported; fresh optimizer)",
    )
    parser.add_argument("--device", choices=("cpu", "cuda"), default=None, help="shorthand for --set run.device=...")
    parser.add_argument(
        "--vgg-weights", default=None, help="torchvision VGG16 state dict (shorthand for run.vgg_weights)"
    )
    parser.add_argument("--optimize", action="store_true", help="run the direct per-volume optimisation baseline")
    parser.add_argument("--checkpoint", type=Path, default=None, help="with --optimize: the network to compare against")
    parser.add_argument("--optimize-steps", type=int, default=None, help="with --optimize: steps per volume (300)")
    parser.add_argument("--optimize-styles", type=int, default=None, help="with --optimize: held-out styles (3)")
    parser.add_argument(
        "--quiet", action="store_true", help="no progress bar or status lines (errors are still printed)"
    )
    args = parser.parse_args(argv)

    from ..progress import set_quiet

    set_quiet(args.quiet)

    from ..backend import BackendError
    from ..model.config import ConfigError

    overrides = list(args.overrides)
    if args.device:
        overrides.append(f'run.device="{args.device}"')
    if args.vgg_weights:
        overrides.append(f"run.vgg_weights={json.dumps(args.vgg_weights)}")
    from ..stops import run_stoppable

    if args.recipe:
        kept = f"finished stages and checkpoints in {args.out} are kept; run the same command again to resume"
    else:
        kept = f"the checkpoints already saved in {args.out} are kept; continue with --resume"
    try:
        return run_stoppable(lambda: _train(args, overrides), kept, in_process=argv is not None)
    except (ConfigError, ValueError, OSError, BackendError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    finally:
        import torch.distributed as dist

        if dist.is_initialized():
            dist.destroy_process_group()


def _train(args, overrides: list[str]) -> int:
    """The command's work, holding ``--out``'s lock (the first process of a distributed run holds it)."""
    import contextlib

    from ..ownership import output_lock

    if args.out.exists() and not args.out.is_dir():
        raise ValueError(f"The output path {args.out} is a file; choose a folder for --out.")
    first = int(os.environ.get("RANK", "0")) == 0
    with output_lock(args.out) if first else contextlib.nullcontext():
        return _train_locked(args, overrides)


def _train_locked(args, overrides: list[str]) -> int:
    """A recipe, a direct optimisation or a training run."""
    from ..model.config import load_config

    distributed = int(os.environ.get("WORLD_SIZE", "1")) > 1
    if args.recipe:
        from .recipes import recipe, run_recipe

        if args.init or args.resume or args.optimize:
            raise ValueError(
                "--recipe runs its own stages (and resumes them by itself); drop --init/--resume/--optimize."
            )
        from .trainer import Interrupted

        try:
            chosen = run_recipe(recipe(args.recipe), args.out, overrides)
        except Interrupted:
            print(f"stopped; run the same command again to resume the recipe in {args.out}", file=sys.stderr)
            return 130
        print(f"done: {chosen}  (stages and choices: {args.out / 'recipe.json'})")
        return 0
    config = load_config(args.config, overrides)
    if not args.optimize and (args.optimize_steps is not None or args.optimize_styles is not None):
        raise ValueError("--optimize-steps and --optimize-styles set the direct optimisation: add --optimize.")
    steps = 300 if args.optimize_steps is None else args.optimize_steps
    styles = 3 if args.optimize_styles is None else args.optimize_styles
    if not (steps >= 1 and styles >= 1):
        raise ValueError(f"--optimize-steps and --optimize-styles must be >= 1, got {steps} and {styles}.")
    if args.optimize:
        from .baseline import compare_with_direct_fit
        from .run_folder import check_run_folder, record_files

        check_run_folder(args.out, resume=False)
        code = compare_with_direct_fit(config, args.out, args.checkpoint, steps, styles)
        record_files(args.out, rewritten=["baseline.json"])
        return code
    if distributed:
        _init_distributed(config)
    from .trainer import Interrupted, Trainer

    if args.init and args.resume:
        raise ValueError(
            "--init starts a new run from a checkpoint's weights; --resume continues one: give one of them."
        )
    created = not args.out.exists()
    try:
        trainer = Trainer(config, args.out, resume=args.resume, init=args.init)
    except BaseException:
        if created:  # a run that never started leaves no folder behind
            import shutil

            shutil.rmtree(args.out, ignore_errors=True)
        raise
    try:
        final = trainer.run()
    except Interrupted:
        print(
            f"stopped at step {trainer.step}; checkpoint {args.out / 'last.pt'}; continue with --resume",
            file=sys.stderr,
        )
        return 130
    if trainer.rank == 0:
        print(f"done: {final}  (metrics {args.out / 'metrics.jsonl'}, previews {args.out / 'previews'})")
    return 0


def _init_distributed(config) -> None:
    import torch.distributed as dist

    backend = "nccl" if config.run.device == "cuda" else "gloo"
    dist.init_process_group(backend=backend)


if __name__ == "__main__":
    sys.exit(main())
