"""Does the network's own pattern hide the style's structure on dense clouds? (#48 part 3e)

On the held-out split the default output's render is closer to the style's structure than tuned noise
+ colour match on 13 of 14 pairs of the thin smoke but on 3 of 14 of the dense pyroclastic cloud, where
the solid texture alone wins 11 of 14. Broken down by pyramid level (``objective.structure``), the
dense cloud's loss is in the orientation of its coarse gradients (4 px and up at 256^2): there the
default's orientations are as far from the style's as isotropic noise's. A dense cloud shows the albedo
of its visible skin, where the network's logits follow the density's puffs; the look's texture (a solid
texture of the style, the default's start) is added to those logits before the head's tanh.

Arms, each the default look with the network's share of the head's logits scaled at the start of the
fit (the last decoder convolution's weight and bias, which the look tunes, so the fit can regrow it):

* ``look_share0``: the network's logits start at zero: the look starts from the texture alone;
* ``look_share_half``: they start at half.

Pairs and scoring: ``solid_texture_study``'s six validation pairs (two validation densities with two
validation styles, two real volumes the real split's reported rows do not use), 256^2, 64 spp, OIDN,
with the default output (``default``) scored again in the same run as the reference.

Rule written before the rows: an arm replaces the default if its median structure distance is at
least 0.02 below the default's and its median RGB and patch SWD are each at most 1.05x the default's;
of several, the lowest structure; ties (within 0.01) go to the larger share.

    .venv/bin/python experiments/look_share_study.py              # about 10 min on 2 cores
    .venv/bin/python experiments/look_share_study.py --heldout    # the chosen arm on the held-out split
    .venv/bin/python experiments/look_share_study.py --report-only
"""

from __future__ import annotations

import copy
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "experiments"))

OUT = ROOT / "results" / "look_share_study"
SHARES = {"look_share0": 0.0, "look_share_half": 0.5}


def scaled_stylizer(stylizer, share: float):
    """A copy of ``stylizer`` whose network's last convolution (weight and bias) is scaled by ``share``."""
    import torch

    scaled = copy.copy(stylizer)
    scaled.trained = copy.copy(stylizer.trained)
    scaled.trained.model = copy.deepcopy(stylizer.trained.model)
    with torch.no_grad():
        for parameter in scaled.trained.model.decoder[2].parameters():
            parameter.mul_(share)
    return scaled


def register_arms() -> list[str]:
    """The arms as benchmark methods (a study's hook into the registry; the product's methods are unchanged)."""
    from mistyle.benchmark.methods import METHODS, Method
    from mistyle.pipeline import Pipeline, PipelineSettings

    pipelines = {}

    def arm(name, share):
        def albedo(context, density, style):
            if name not in pipelines:
                stylizer = scaled_stylizer(context.stylizer, share)
                settings = PipelineSettings(checkpoint=stylizer.path, refine_steps=0, refine_path_steps=0)
                pipelines[name] = Pipeline(settings, stylizer=stylizer)
            return pipelines[name].fit_look(density, style).stylize(density)

        return albedo

    for name, share in SHARES.items():
        METHODS[name] = Method(
            name, "ablation", f"the default look, the network's logits x {share} at the start", arm(name, share), True
        )
    return list(SHARES)


def main(argv=None) -> None:
    from solid_texture_study import pairs
    from study import arm_study

    arm_study(__doc__.splitlines()[0], OUT, register_arms, pairs, argv)


if __name__ == "__main__":
    main()
