"""``python -m mistyle.train --optimize``: the network against direct per-volume optimisation.

On a held-out density, for a few held-out styles: a grey albedo, the network's feed-forward albedo
(``--checkpoint``) and an albedo fitted directly through the fast layer (``mistyle.fit``) with the
run's objective, light, views and TV weight, each scored by the sliced Wasserstein distance to
the style on held-out views. Writes ``baseline.json`` into the run directory.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

from ..bridge_torch import render_views
from ..files import atomic_write_bytes
from ..fit import FitSettings, fit_albedo
from ..integrators import prepare_density
from ..model.checkpoint import load_checkpoint, model_from_checkpoint
from ..model.config import TrainConfig
from ..model.features import make_extractor
from ..objective.metrics import style_distance
from ..objective.style import StyleObjective
from ..scenes import CameraPath
from .dataset import SmokePairs, StyleSet
from .trainer import device_for

GREY = 0.5


def compare_with_direct_fit(
    config: TrainConfig, out: Path, checkpoint: Path | None, steps: int, style_count: int
) -> int:
    device = device_for(config)  # the layer runs in the variant of the albedo's device: keep tensors there
    network = None
    if checkpoint is not None:  # the network from the checkpoint; data, light and views from --config/--set
        network, trained = model_from_checkpoint(load_checkpoint(checkpoint), checkpoint)
        network = network.to(device)
        config.model = trained.model
    data = SmokePairs(config.data.smoke, config.data.val_plumes, config.data.make)
    styles = StyleSet(config.data.styles, config.data.style_size)
    extractor = make_extractor(config.run.extractor, config.run.vgg_weights or None).to(device)
    print(f"feature extractor: {extractor.name}", file=sys.stderr)
    if network is not None and tuple(extractor.channels) != tuple(config.model.style_channels):
        raise ValueError(
            f"{checkpoint} was trained with another feature extractor than {extractor.name}; "
            "set run.extractor (and --vgg-weights) as in its training config."
        )
    objective = StyleObjective(extractor, config.loss.style, config.loss.rgb_weight)
    render = config.render
    orbit = CameraPath(distance=render.camera_distance)
    held_out_views = orbit.held_out(4)
    frame = data.load(data.val[len(data.val) // 2])
    prepared = prepare_density(frame["density0"], data.density_scale, ls=frame["ls0"])
    density = torch.from_numpy(frame["density0"])[None, None].to(device)

    def layer(albedo, views, seed=0):
        return render_views(albedo, prepared, views, render.image_size, steps=render.steps, radiance=render.radiance)

    def quality(albedo, style_np):
        with torch.no_grad():
            images = layer(albedo, held_out_views)
        return float(
            np.mean([style_distance(image.permute(1, 2, 0).cpu().numpy(), style_np)["swd"] for image in images])
        )

    settings = FitSettings(
        steps=steps,
        views_per_step=render.views,
        tv_weight=config.loss.tv_weight,
        camera_distance=render.camera_distance,
    )
    rows = []
    for index in styles.comparison_styles(min(style_count, len(styles.val))):
        style = styles.val[index].to(device)
        style_np = style.permute(1, 2, 0).cpu().numpy()
        grey = torch.full((3,) + prepared.shape, GREY, device=device)
        row = {"style": styles.val_names[index], "swd_grey": quality(grey, style_np)}
        if network is not None:
            started = time.perf_counter()
            with torch.no_grad():
                albedo = network(density, network.encode_style(style[None], extractor))[0]
            row.update(network_seconds=time.perf_counter() - started, swd_network=quality(albedo, style_np))
        fit = fit_albedo(layer, style, objective, grey, settings)
        row.update(optimize_seconds=fit.seconds, optimize_steps=steps, swd_optimized=quality(fit.albedo, style_np))
        rows.append(row)
        print(json.dumps(row), flush=True)
    summary = {key: float(np.mean([r[key] for r in rows])) for key in rows[0] if key != "style"}
    print(json.dumps({"mean": summary}))
    atomic_write_bytes(
        Path(out) / "baseline.json", (json.dumps({"rows": rows, "mean": summary}, indent=1) + "\n").encode()
    )
    return 0
