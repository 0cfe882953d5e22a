"""The probe that chose ``look_structure_study``'s weights: three dense validation pairs, many arms.

Before the 28-pair study, on ``val_pyroclastic64`` with Klimt's Kiss, NASA's Io and a rosewood veneer
(256^2, 64 spp, OIDN, as users see it), the default look, tuned noise and the solid texture next to:

* ``look_gradientW``: the objective's gradient term (``LookSettings.structure_weight``) weighted
  0.003, 0.01, 0.03, 0.1, 0.3 or 1;
* ``look_detailK_S``: the default look, then the solid texture's fine band (the texture's start minus
  its Gaussian blur of S texels, times K) added to the fitted texture: strokes the fit's 64^2 views
  cannot see, laid on after it (K 1 and 2, S 1.5).

Three pairs decide nothing (``results/structure_seed_spread/``); this only picked the weights the study
tests. Rows in ``results/look_structure_study/probe/``.

    .venv/bin/python experiments/look_structure_probe.py        # about 15 min on 2 cores
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "experiments"))

OUT = ROOT / "results" / "look_structure_study" / "probe"
WEIGHTS = {"look_gradient003": 0.003, "look_gradient01": 0.01, "look_gradient03": 0.03, "look_gradient1": 0.1}
WEIGHTS |= {"look_gradient3": 0.3, "look_gradient10": 1.0}
BANDS = {"look_detail1_1.5": (1.0, 1.5), "look_detail2_1.5": (2.0, 1.5)}


def blurred(texture, sigma: float):
    """``texture (C, tz, ty, tx)`` blurred by a Gaussian of ``sigma`` texels along each axis (edges repeated)."""
    import torch
    import torch.nn.functional as F

    radius = int(3 * sigma)
    taps = torch.exp(-0.5 * (torch.arange(-radius, radius + 1, dtype=torch.float32) / sigma) ** 2)
    taps = taps / taps.sum()
    volume = texture[:, None]
    for axis in range(3):
        shape, pad = [1, 1, 1, 1, 1], [0] * 6
        shape[2 + axis] = -1
        pad[2 * (2 - axis)] = pad[2 * (2 - axis) + 1] = radius
        volume = F.conv3d(F.pad(volume, pad, mode="replicate"), taps.view(shape))
    return volume[:, 0]


def register_arms() -> list[str]:
    from mistyle.benchmark.methods import METHODS, Method
    from mistyle.look import LookSettings, solid_texture_start
    from mistyle.style import Style

    def gradient(weight):
        def albedo(context, density, style):
            pipeline = context.pipeline(refine_steps=0, refine_path_steps=0)
            return pipeline.fit_look(density, style, look_settings=LookSettings(structure_weight=weight)).stylize(
                density
            )

        return albedo

    def band(strength, sigma):
        def albedo(context, density, style):
            pipeline = context.pipeline(refine_steps=0, refine_path_steps=0)
            settings = LookSettings(structure_weight=0.0)  # the default look of the probe's time
            look = pipeline.fit_look(density, style, look_settings=settings)
            start = solid_texture_start(Style.of(style).target, tuple(look.texture.shape[1:]), 4.0, settings.seed)
            look.texture = look.texture + strength * (start - blurred(start, sigma)).to(look.texture)
            return look.stylize(density)

        return albedo

    for name, weight in WEIGHTS.items():
        METHODS[name] = Method(name, "ablation", f"the look, gradient term weighted {weight}", gradient(weight), True)
    for name, (strength, sigma) in BANDS.items():
        METHODS[name] = Method(
            name, "ablation", "the look plus the solid texture's fine band", band(strength, sigma), True
        )
    return list(WEIGHTS) + list(BANDS)


def main() -> None:
    from study import USER_SCORING

    from mistyle.benchmark.runner import run
    from mistyle.benchmark.splits import split_pairs

    arms = register_arms()
    styles = ["klimt_the_kiss", "photo_nasa_io_global", "texture_rosewood_veneer"]
    pairs = split_pairs("validation", ["val_pyroclastic64"], styles)
    methods = ["default", "tuned_noise", "solid_texture"] + arms
    run(OUT, pairs, methods, split="validation", resume=True, **USER_SCORING)


if __name__ == "__main__":
    main()
