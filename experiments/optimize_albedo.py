"""Optimise an albedo grid directly (no network) against a style, through the fast layer.

Albedo = sigmoid(logits) on the density's grid; each step renders 4 random views on the training
orbit, tone-maps them, and minimises the histogram loss on the extractor's four feature levels
plus the same loss in RGB, and 3D TV (paper weights 1 and 10). The style match is measured as
the sliced Wasserstein distance between held-out views' foreground pixels and the style image.

Prints one JSON line per (extractor, style) and a summary line with the keys ``swd_before``,
``swd_after``, ``steps``, ``seconds`` and ``extractor`` (means over styles, per extractor), plus
``swd_opaque_*``: the same distance over the pixels whose opacity exceeds 0.5, which leaves out
the thin fringe that no albedo can make bright.

    python experiments/optimize_albedo.py --quick                 # 32^3, 48^2 views, 60 steps
    python experiments/optimize_albedo.py --extractors filterbank vgg16-random --styles 3
"""

from __future__ import annotations

import argparse
import json

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
    parser.add_argument(
        "--radiance", type=float, default=None, help="constant environment radiance Le (default: the training light)"
    )
    args = parser.parse_args()
    if args.quick:
        args.image, args.res = 48, 32
        args.steps = min(args.steps, 150)
    torch.manual_seed(0)

    from mistyle.bridge_torch import render_views
    from mistyle.conventions import DEFAULT_ENV_RADIANCE
    from mistyle.data.styles import material_texture, offline_style_set
    from mistyle.files import load_density
    from mistyle.fit import FitSettings, fit_albedo
    from mistyle.integrators import PreparedDensity, prepare_density
    from mistyle.model.features import make_extractor
    from mistyle.objective.metrics import sliced_wasserstein, style_distance
    from mistyle.objective.style import StyleObjective
    from mistyle.scenes import CameraPath
    from mistyle.tone import tone_map

    if args.radiance is None:
        args.radiance = DEFAULT_ENV_RADIANCE

    density = load_density("examples/smoke_64.vol")
    if args.res != density.shape[0]:
        t = torch.from_numpy(density)[None, None]
        density = torch.nn.functional.interpolate(t, size=(args.res,) * 3, mode="trilinear", align_corners=False)[
            0, 0
        ].numpy()
    prepared = prepare_density(density, 30.0)
    held_out = CameraPath().held_out(4)
    styles = [
        ("material/marble", material_texture("marble", 128, seed=3)),
        ("material/fire", material_texture("fire", 128, seed=3)),
    ]
    styles += [
        s
        for s in offline_style_set(
            size=128, crops_per_photo=1, palettes_per_texture=1, materials_each=0, crops_per_painting=0
        )
        if s[0].startswith("photo/coffee") or s[0].startswith("photo/hubble")
    ]
    styles = styles[: args.styles]

    # Opacity 1 - T per pixel: with Ls = 1, albedo 1 and Le = 1 the layer's exact segments sum to 1 - T.
    with torch.no_grad():
        opacity = render_views(
            torch.ones((3,) + prepared.shape),
            PreparedDensity(prepared.density, prepared.density_scale, np.ones_like(prepared.ls)),
            held_out,
            args.image,
            radiance=1.0,
        )[:, 0]

    def held_out_swd(albedo: torch.Tensor, style: np.ndarray) -> tuple[float, float]:
        """SWD over every foreground pixel (the metric) and over the opaque ones (opacity > 0.5) only."""
        with torch.no_grad():
            images = render_views(albedo, prepared, held_out, args.image, radiance=args.radiance)
        every = np.mean([style_distance(img.permute(1, 2, 0).numpy(), style)["swd"] for img in images])
        opaque = tone_map(images.permute(0, 2, 3, 1)[opacity > 0.5]).numpy()
        return float(every), sliced_wasserstein(opaque, style.reshape(-1, 3))

    summary = {}
    for kind in args.extractors:
        extractor = make_extractor(kind)
        objective = StyleObjective(extractor)
        results = []
        for name, style in styles:
            style_tensor = torch.from_numpy(style).permute(2, 0, 1)
            before, opaque_before = held_out_swd(torch.full((3,) + prepared.shape, 0.5), style)

            def layer(albedo, views, seed=0):
                return render_views(albedo, prepared, views, args.image, radiance=args.radiance)

            fit = fit_albedo(
                layer,
                style_tensor,
                objective,
                torch.full((3,) + prepared.shape, 0.5),
                FitSettings(steps=args.steps, lr=args.lr),
            )
            after, opaque_after = held_out_swd(fit.albedo, style)
            row = {
                "extractor": extractor.name,
                "style": name,
                "radiance": args.radiance,
                "swd_before": before,
                "swd_after": after,
                "swd_opaque_before": opaque_before,
                "swd_opaque_after": opaque_after,
                "steps": args.steps,
                "seconds": fit.seconds,
            }
            results.append(row)
            print(json.dumps(row), flush=True)
        keys = ("swd_before", "swd_after", "swd_opaque_before", "swd_opaque_after", "seconds")
        summary[extractor.name] = {key: float(np.mean([r[key] for r in results])) for key in keys}
    for name, values in summary.items():
        print(json.dumps({"extractor": name, "steps": args.steps, **values}))


if __name__ == "__main__":
    main()
