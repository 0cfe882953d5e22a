"""Optimise an albedo grid directly (no network) against a style, through the fast layer.

Albedo = sigmoid(logits) on the density's grid; each step renders 4 random views on the training
orbit, tone-maps them, and minimises the histogram loss on the extractor's four feature levels
plus the same loss in RGB, and 3D TV (paper weights 1 and 10). The style match is measured as
the sliced Wasserstein distance between held-out views' foreground pixels and the style image.

Prints one JSON line per (extractor, style) and a summary line with the keys ``swd_before``,
``swd_after``, ``steps``, ``seconds`` and ``extractor`` (means over styles, per extractor).

    python experiments/optimize_albedo.py --quick                 # 32^3, 48^2 views, 60 steps
    python experiments/optimize_albedo.py --extractors filterbank vgg16-random --styles 3
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--extractors", nargs="+", default=["auto"])
    parser.add_argument("--styles", type=int, default=3)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--image", type=int, default=96)
    parser.add_argument("--res", type=int, default=64)
    parser.add_argument("--lr", type=float, default=0.05)
    parser.add_argument("--radiance", type=float, default=1.0, help="constant environment radiance Le")
    args = parser.parse_args()
    if args.quick:
        args.image, args.res = 48, 32
        args.steps = min(args.steps, 150)
    torch.manual_seed(0)

    from mistyle.bridge_torch import render_views
    from mistyle.data.styles import material_texture, offline_style_set
    from mistyle.scenes import CameraPath, prepare_density
    from mistyle.train.features import make_extractor
    from mistyle.train.losses import (
        histogram_loss,
        pool_mask,
        render_mask,
        tone_map,
        tv_loss,
    )
    from mistyle.train.metrics import style_distance
    from mistyle.volume import load_density

    density = load_density("examples/smoke_64.vol")
    if args.res != density.shape[0]:
        t = torch.from_numpy(density)[None, None]
        density = torch.nn.functional.interpolate(t, size=(args.res,) * 3, mode="trilinear", align_corners=False)[0, 0].numpy()
    prepared = prepare_density(density, 30.0)
    path = CameraPath()
    held_out = path.turntable(4, offset=0.0625)
    size = (args.image, args.image)
    styles = [("material/marble", material_texture("marble", 128, seed=3)), ("material/fire", material_texture("fire", 128, seed=3))]
    styles += [s for s in offline_style_set(size=128, crops_per_photo=1, palettes_per_texture=1, materials_each=0) if s[0].startswith("photo/coffee") or s[0].startswith("photo/hubble")]
    styles = styles[: args.styles]

    def held_out_swd(albedo: torch.Tensor, style: np.ndarray) -> float:
        with torch.no_grad():
            images = render_views(albedo, prepared, held_out, size, radiance=args.radiance)
        return float(np.mean([style_distance(img.permute(1, 2, 0).numpy(), style)["swd"] for img in images]))

    summary = {}
    for kind in args.extractors:
        extractor = make_extractor(kind)
        results = []
        for name, style in styles:
            style_tensor = torch.from_numpy(style).permute(2, 0, 1)[None]
            with torch.no_grad():
                style_levels = [level[0] for level in extractor(style_tensor)]
            logits = torch.zeros((3,) + density.shape, requires_grad=True)
            optimizer = torch.optim.Adam([logits], lr=args.lr)
            before = held_out_swd(torch.sigmoid(logits), style)
            rng = np.random.default_rng(0)
            start = time.perf_counter()
            for _ in range(args.steps):
                albedo = torch.sigmoid(logits)
                images = tone_map(render_views(albedo, prepared, path.sample(4, rng), size, radiance=args.radiance))
                mask = render_mask(images)
                loss = histogram_loss(images, style_tensor[0], mask)  # RGB
                for level, target in zip(extractor(images), style_levels):
                    loss = loss + histogram_loss(level, target, pool_mask(mask, level.shape[-2:]))
                loss = loss + 10.0 * tv_loss(albedo[None])
                optimizer.zero_grad()
                loss.backward()
                optimizer.step()
            seconds = time.perf_counter() - start
            after = held_out_swd(torch.sigmoid(logits), style)
            row = {"extractor": extractor.name, "style": name, "radiance": args.radiance, "swd_before": before, "swd_after": after,
                   "steps": args.steps, "seconds": seconds}
            results.append(row)
            print(json.dumps(row), flush=True)
        summary[extractor.name] = {key: float(np.mean([r[key] for r in results])) for key in ("swd_before", "swd_after", "seconds")}
    for name, values in summary.items():
        print(json.dumps({"extractor": name, "steps": args.steps, **values}))


if __name__ == "__main__":
    main()
