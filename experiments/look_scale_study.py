"""Does the look's fit compare its renders with the style at the wrong scale? (#48 parts 3e and 4)

The benchmark (and a user) sees a 256^2 render next to a style of about 256 px: pixel for pixel, one
scale. The look's fit renders 64^2 views and compares them with the style squared to 128 px
(``objective.style.SLICED_STYLE_SIZE``): a 5x5 patch covers twice the share of the view that it
covers of the style, so the fit asks the medium for the style's strokes at twice their size, and the
texture's finer detail (a voxel is under a pixel of a 64^2 view of a 64^3 grid) is seen only by the
smoothness term. On the held-out dense cloud the default output's render is smoother than the solid
texture it starts from (``results/look_share_study/README.md``).

Arms, each the default look with the view side (``LookSettings.layer_res``) and the style's side in
the objective changed, the default (64 px views, style at 128 px) scored in the same session at the same code (its rows
from ``look_share_study``):

* ``look_style64``: the style at 64 px, as the views: one scale, at the default's cost;
* ``look_res96``: 96 px views, the style at 96 px;
* ``look_res128``: 128 px views, the style at 128 px (as the default's).

Pairs and scoring: ``solid_texture_study``'s six validation pairs, 256^2, 64 spp, OIDN.

Rule written before the rows: an arm replaces the default if its median structure distance is at
least 0.02 below the default's, its median RGB and patch SWD are each at most 1.05x the default's, and
its median fit time at most 1.5x the default's (same run); of several, the lowest structure; ties
(within 0.01) go to the cheaper arm.

    .venv/bin/python experiments/look_scale_study.py              # about 15 min on 2 cores
    .venv/bin/python experiments/look_scale_study.py --heldout look_style64
    .venv/bin/python experiments/look_scale_study.py --report-only
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "experiments"))

OUT = ROOT / "results" / "look_scale_study"
ARMS = {"look_style64": (64, 64), "look_res96": (96, 96), "look_res128": (128, 128)}  # (view side, style side)


def register_arms() -> list[str]:
    """The arms as benchmark methods (a study's hook into the registry; the product's methods are unchanged)."""
    import mistyle.objective.style as objective_style
    from mistyle.benchmark.methods import METHODS, Method
    from mistyle.look import LookSettings

    def arm(view_side, style_side):
        def albedo(context, density, style):
            pipeline = context.pipeline(refine_steps=0, refine_path_steps=0)
            shipped = objective_style.SLICED_STYLE_SIZE
            objective_style.SLICED_STYLE_SIZE = style_side  # fit_look reads it at each call
            try:
                look = pipeline.fit_look(density, style, look_settings=LookSettings(layer_res=view_side))
            finally:
                objective_style.SLICED_STYLE_SIZE = shipped
            return look.stylize(density)

        return albedo

    for name, (view_side, style_side) in ARMS.items():
        description = f"the default look fitted on {view_side}^2 views against the style at {style_side} px"
        METHODS[name] = Method(name, "ablation", description, arm(view_side, style_side), True)
    return list(ARMS)


def main(argv=None) -> None:
    from solid_texture_study import pairs
    from study import arm_study

    arm_study(__doc__.splitlines()[0], OUT, register_arms, pairs, argv)


if __name__ == "__main__":
    main()
