"""Does refining a sequence bring back flicker? (issue: style fidelity I, part 3)

A held-out smoke plume (``mistyle.data.heldout``'s smoke64 seed) is simulated and ``--frames``
consecutive frames with their velocities are stylized with the network, then refined three ways:

* ``network``: not refined (``render_final``'s default for sequences): the network with the colour
  match, whose map the frames share (``api.Stylizer`` on the whole sequence);
* ``network alone``: the same without the colour match (``--no-colour-match``);
* ``independent``: every frame refined on its own from its network albedo (no temporal term);
* ``coherent``: ``render_final --refine`` on the sequence: each frame starts from the previous
  refined frame warped by its velocity and is held near it by the temporal term.

Prints per arm the albedo flicker (``temporal_flicker``: mean |V_t - W(V_{t-1})|) and the mean RGB SWD /
hue coverage of the frames (path traced from the held-out view).

    python experiments/sequence_refine.py                  # 4 frames, 2 styles, render_final's defaults
    python experiments/sequence_refine.py --quick          # 2 frames, 1 style, 4 + 1 steps
"""

from __future__ import annotations

import argparse
import json

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=4)
    parser.add_argument("--styles", default="hokusai_great_wave,gauguin_te_fare")
    parser.add_argument("--res", type=int, default=128)
    parser.add_argument("--arms", default="network,network alone,independent,coherent")
    parser.add_argument(
        "--temporal-weights", default=None, help="coherent arm: comma-separated weights (default: render_final's)"
    )
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    if args.quick:
        args.frames, args.styles, args.res = 2, "hokusai_great_wave", 32

    from dataclasses import replace

    from study import metric_views, score

    from mistyle.api import Stylizer
    from mistyle.data.heldout import HELD_OUT_DENSITIES, held_out_styles
    from mistyle.data.smoke import PlumeConfig, simulate
    from mistyle.files import load_style
    from mistyle.fit import refine_albedo
    from mistyle.objective.metrics import temporal_flicker
    from mistyle.pipeline import Pipeline, PipelineSettings, default_refinement

    spec = next(s for s in HELD_OUT_DENSITIES if s.name == "smoke64")
    config = PlumeConfig.random((spec.resolution,) * 3, np.random.default_rng([spec.seed, 0]))
    frames = [(d, v) for t, d, v in simulate(config, spec.frame + args.frames, seed=spec.seed) if t >= spec.frame]
    densities, velocities = [d for d, _ in frames], [v for _, v in frames]
    stylizer = Stylizer()
    scale, radiance = stylizer.density_scale, stylizer.config.render.radiance
    views = metric_views(stylizer.config.render.camera_distance, 1)
    settings = default_refinement(stylizer.config)
    if args.quick:
        settings = replace(settings, layer_steps=4, path_steps=1)
    styles = held_out_styles()
    for name in args.styles.split(","):
        style = load_style(styles[name]["path"])
        alone = list(stylizer(np.stack(densities), style, match_colours=False))
        network = stylizer.match_colours(alone, densities, style)
        chosen = args.arms.split(",")
        arms = {"network": network} if "network" in chosen else {}
        if "network alone" in chosen:
            arms["network alone"] = alone
        if "independent" in chosen:
            arms["independent"] = [
                refine_albedo(d, scale, a, style, settings, radiance=radiance)[0] for d, a in zip(densities, network)
            ]
        weights = (
            [settings.temporal_weight]
            if args.temporal_weights is None
            else map(float, args.temporal_weights.split(","))
        )
        for weight in weights if "coherent" in chosen else ():
            # The pipeline's own sequence refinement (Pipeline.refine), with this temporal weight.
            pipeline = Pipeline(
                PipelineSettings(refine_steps=settings.layer_steps, refine_path_steps=settings.path_steps),
                stylizer=stylizer,
            )
            frames = pipeline.frames(densities, velocities)
            coherent, _ = pipeline.refine(frames, network, style, replace(settings, temporal_weight=weight))
            arms[f"coherent (temporal weight {weight:g})"] = coherent
        for arm, albedos in arms.items():
            metrics = [
                score(d, a, style, views, res=args.res, spp=16, density_scale=scale, radiance=radiance)[0]
                for d, a in zip(densities, albedos)
            ]
            print(
                json.dumps(
                    {
                        "style": name,
                        "arm": arm,
                        "frames": args.frames,
                        "flicker": temporal_flicker(np.stack(albedos), np.stack(velocities)),
                        "rgb_swd": float(np.mean([m["rgb_swd"] for m in metrics])),
                        "patch_swd": float(np.mean([m["patch_swd"] for m in metrics])),
                        "hue_coverage": float(np.mean([m["hue_coverage"] for m in metrics])),
                    }
                ),
                flush=True,
            )


if __name__ == "__main__":
    main()
