"""``python -m mistyle.train``: train SKPN through the fast Mitsuba layer, or run the direct baseline.

    python -m mistyle.train --config configs/cpu.toml --out runs/cpu
    python -m mistyle.train --config configs/cpu.toml --out runs/cpu --resume         # continue exactly
    python -m mistyle.train --config configs/tiny.toml --set optim.steps=50 --out runs/t
    torchrun --nproc_per_node 2 -m mistyle.train --config configs/tiny.toml --out runs/ddp
    python -m mistyle.train --config configs/cpu.toml --optimize --checkpoint runs/cpu/final.pt --out runs/baseline

``--optimize`` fits albedo grids directly (no network) to held-out styles on held-out densities
with the run's objective and light, and compares them with the network's feed-forward albedo
(``--checkpoint``) in quality (sliced Wasserstein distance on held-out views) and time.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mistyle.train", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", type=Path, required=True, help="a TOML file, e.g. configs/cpu.toml")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override one config value (repeatable), e.g. --set optim.lr=1e-4")
    parser.add_argument("--out", type=Path, required=True, help="run directory (checkpoints, metrics, previews)")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out from its last.pt")
    parser.add_argument("--device", choices=("cpu", "cuda"), default=None, help="shorthand for --set run.device=...")
    parser.add_argument("--vgg-weights", default=None, help="torchvision VGG16 state dict (shorthand for run.vgg_weights)")
    parser.add_argument("--optimize", action="store_true", help="run the direct per-volume optimisation baseline")
    parser.add_argument("--checkpoint", type=Path, default=None, help="with --optimize: the network to compare against")
    parser.add_argument("--optimize-steps", type=int, default=300)
    parser.add_argument("--optimize-styles", type=int, default=3)
    args = parser.parse_args(argv)

    from ..backend import BackendError
    from .config import ConfigError, load_config

    overrides = list(args.overrides)
    if args.device:
        overrides.append(f'run.device="{args.device}"')
    if args.vgg_weights:
        overrides.append(f"run.vgg_weights={json.dumps(args.vgg_weights)}")
    distributed = int(os.environ.get("WORLD_SIZE", "1")) > 1
    try:
        config = load_config(args.config, overrides)
        if args.optimize:
            return _baseline(config, args)
        if distributed:
            _init_distributed(config)
        from .trainer import Interrupted, Trainer

        trainer = Trainer(config, args.out, resume=args.resume)
        try:
            final = trainer.run()
        except Interrupted:
            print(f"stopped at step {trainer.step}; checkpoint {args.out / 'last.pt'}; continue with --resume", file=sys.stderr)
            return 130
        if trainer.rank == 0:
            print(f"done: {final}  (metrics {args.out / 'metrics.jsonl'}, previews {args.out / 'previews'})")
        return 0
    except (ConfigError, ValueError, OSError, BackendError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    finally:
        import torch.distributed as dist

        if dist.is_initialized():
            dist.destroy_process_group()


def _init_distributed(config) -> None:
    import torch.distributed as dist

    backend = "nccl" if config.run.device == "cuda" else "gloo"
    dist.init_process_group(backend=backend)


def _baseline(config, args) -> int:
    """Network feed-forward vs direct optimisation on held-out densities and styles."""
    import numpy as np
    import torch

    from ..bridge_torch import render_views
    from ..io import atomic_write_bytes
    from ..scenes import CameraPath, prepare_density
    from .dataset import SmokePairs, StyleSet
    from .features import make_extractor
    from .metrics import style_distance
    from .objective import StyleObjective
    from .optimize import optimize_albedo
    from .trainer import device_for, load_model

    device_for(config)
    network = None
    if args.checkpoint is not None:  # the network from the checkpoint; data, light and views from --config/--set
        network, trained = load_model(args.checkpoint)
        config.model = trained.model
    data = SmokePairs(config.data.smoke, config.data.val_plumes, config.data.make)
    styles = StyleSet(config.data.styles, config.data.style_size)
    extractor = make_extractor(config.run.extractor, config.run.vgg_weights or None)
    print(f"feature extractor: {extractor.name}", file=sys.stderr)
    if network is not None and tuple(extractor.channels) != tuple(config.model.style_channels):
        raise ValueError(f"{args.checkpoint} was trained with another feature extractor than {extractor.name}; "
                         "set run.extractor (and --vgg-weights) as in its training config.")
    objective = StyleObjective(extractor, config.loss.style, config.loss.rgb_weight)
    render = config.render
    held_out_views = CameraPath(distance=render.camera_distance).turntable(4, offset=0.0625)
    frame = data.load(data.val[len(data.val) // 2])
    prepared = prepare_density(frame["density0"], data.density_scale, ls=frame["ls0"])
    density = torch.from_numpy(frame["density0"])[None, None]

    def quality(albedo, style_np):
        with torch.no_grad():
            images = render_views(albedo, prepared, held_out_views, render.image_size, steps=render.steps, radiance=render.radiance)
        return float(np.mean([style_distance(image.permute(1, 2, 0).numpy(), style_np)["swd"] for image in images]))

    rows = []
    picks = styles.comparison_styles(min(args.optimize_styles, len(styles.val)))
    for index in picks:
        style = styles.val[index]
        style_np = style.permute(1, 2, 0).numpy()
        row = {"style": styles.val_names[index], "swd_grey": quality(torch.full((3,) + prepared.shape, 0.5), style_np)}
        if network is not None:
            started = time.perf_counter()
            with torch.no_grad():
                albedo = network(density, list(extractor(style[None])))[0]
            row.update(network_seconds=time.perf_counter() - started, swd_network=quality(albedo, style_np))
        fit = optimize_albedo(prepared, style, objective, steps=args.optimize_steps, image_size=render.image_size,
                              views=render.views, render_steps=render.steps, radiance=render.radiance,
                              tv_weight=config.loss.tv_weight, camera_distance=render.camera_distance)
        row.update(optimize_seconds=fit.seconds, optimize_steps=args.optimize_steps, swd_optimized=quality(fit.albedo, style_np))
        rows.append(row)
        print(json.dumps(row), flush=True)
    summary = {key: float(np.mean([r[key] for r in rows])) for key in rows[0] if key != "style"}
    print(json.dumps({"mean": summary}))
    atomic_write_bytes(args.out / "baseline.json", (json.dumps({"rows": rows, "mean": summary}, indent=1) + "\n").encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
