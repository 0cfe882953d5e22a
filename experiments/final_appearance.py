"""How far path-traced finals are from the style, and whether the corrections help (issue: final appearance).

For unseen styles (the checkpoint's held-out styles) on an unseen density (the bundled 64^3 smoke
frame), the network's albedo is rendered four ways from the same held-out views, with the same
resolution and samples:

* ``layer``: the fast layer (single scattering, the training renderer);
* ``plain``: ``volpath`` with multiple scattering, albedo as predicted;
* ``calibrated``: ``volpath`` with the multiple-scattering albedo calibration (``mistyle.correct``);
* ``refined``: the calibrated albedo refined for ``--refine`` steps with the path tracer in the loop;
* ``refined_plain``: the predicted albedo (no calibration) refined the same way.

Each prints its sliced Wasserstein distance to the style (lower is closer) and the seconds it took.

    python experiments/final_appearance.py                     # 3 styles, 4 views at 96^2, 64 spp
    python experiments/final_appearance.py --quick             # 1 style, 2 views at 48^2, 16 spp
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--checkpoint", default=None)
    parser.add_argument("--density", default="examples/smoke_64.vol")
    parser.add_argument("--styles", type=int, default=3)
    parser.add_argument("--views", type=int, default=4)
    parser.add_argument("--res", type=int, default=96)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--refine", type=int, default=16)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    if args.quick:
        args.styles, args.views, args.res, args.spp, args.refine = 1, 2, 48, 16, 2

    import torch

    from mistyle.api import Stylizer, path_trace
    from mistyle.bridge_torch import render_views
    from mistyle.correct import measure_calibration
    from mistyle.fit import refine_albedo
    from mistyle.integrators import prepare_density
    from mistyle.io import load_density
    from mistyle.objective.metrics import style_distance
    from mistyle.objective.style import StyleObjective
    from mistyle.render_final import REFINE_RES, REFINE_SPP, refine_settings
    from mistyle.scenes import CameraPath
    from mistyle.train.dataset import StyleSet

    stylizer = Stylizer(args.checkpoint)
    config = stylizer.config
    radiance, scale = config.render.radiance, stylizer.density_scale
    density = load_density(args.density)
    prepared = prepare_density(density, scale)
    orbit = CameraPath(distance=config.render.camera_distance)
    views = orbit.held_out(args.views)
    styles = StyleSet(config.data.styles, 128)
    picks = styles.comparison_styles(min(args.styles, len(styles.val)))
    objective = StyleObjective(stylizer.extractor, config.loss.style, config.loss.rgb_weight)
    settings = refine_settings(config, args.refine, config.render.camera_distance)

    def swd(images, style):
        return float(np.mean([style_distance(image, style)["swd"] for image in images]))

    def traced(albedo):
        images, seconds = path_trace(density, albedo, views, res=args.res, spp=args.spp, density_scale=scale,
                                     light=f"constant:{radiance}")
        return images, sum(seconds)

    started = time.perf_counter()
    calibration = measure_calibration(density, scale, radiance, views[:2], res=64, spp=16, prepared=prepared)
    rows = []
    for index in picks:
        style = styles.val[index].permute(1, 2, 0).numpy()
        began = time.perf_counter()
        albedo = stylizer(density, style)
        row = {"style": styles.val_names[index], "stylize_seconds": time.perf_counter() - began}
        with torch.no_grad():
            layer = render_views(torch.from_numpy(albedo).permute(3, 0, 1, 2), prepared, views, args.res, radiance=radiance)
        row["swd_layer"] = swd([image.permute(1, 2, 0).numpy() for image in layer], style)
        images, row["plain_seconds"] = traced(albedo)
        row["swd_plain"] = swd(images, style)
        calibrated = calibration.apply(albedo)
        images, _ = traced(calibrated)
        row["swd_calibrated"] = swd(images, style)
        target = stylizer.style_tensor(style)
        refined, row["refine_seconds"] = refine_albedo(density, scale, calibrated, target, objective, settings,
                                                       res=REFINE_RES, spp=REFINE_SPP, radiance=radiance)
        images, _ = traced(refined)
        row["swd_refined"] = swd(images, style)
        refined, _ = refine_albedo(density, scale, albedo, target, objective, settings, res=REFINE_RES, spp=REFINE_SPP,
                                   radiance=radiance)
        images, _ = traced(refined)
        row["swd_refined_plain"] = swd(images, style)
        rows.append(row)
        print(json.dumps(row), flush=True)
    mean = {key: float(np.mean([r[key] for r in rows])) for key in rows[0] if key != "style"}
    print(json.dumps({"mean": mean, "calibration_seconds": calibration.seconds, "views": args.views, "res": args.res,
                      "spp": args.spp, "refine_steps": args.refine, "seconds": time.perf_counter() - started}))


if __name__ == "__main__":
    main()
