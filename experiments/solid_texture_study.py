"""Does a solid texture of the style give the look the style's structure? (#48 parts 3-5)

Arms, each a look fitted on the pair's density and applied (``benchmark.methods``' ``look``), differing
only in how the look's texture starts (``LookSettings.texture_start``), next to the training-free
baselines with the product's colour match:

* ``look_zeros``: today's look (a 32-texel texture started at zero);
* ``look_solid2``/``look_solid4``: a 64-texel texture started from a solid texture of the style
  (``mistyle.solid_texture``), scaled by 2 or 4 in the head's logits;
* ``solid_texture``, ``tuned_noise``: the baselines.

Chosen on validation pairs only: two of the validation split's densities and two real volumes that the
real split's reported rows do not use (``usd_puff``, ``mitsuba_smoke``), with validation styles.
Rule written before the rows: the arm with the lowest median structure distance whose median RGB SWD is
at most 1.05x ``look_zeros``'s becomes the default; ties (within 0.01 structure) go to the cheaper arm.

    .venv/bin/python experiments/solid_texture_study.py            # about 40 min on 2 cores
    .venv/bin/python experiments/solid_texture_study.py --report-only
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

OUT = ROOT / "results" / "solid_texture_study"
DENSITIES = ("val_smoke64", "val_pyroclastic64")
REAL_DENSITIES = ("usd_puff", "mitsuba_smoke")
STYLES = ("klimt_the_kiss", "photo_nasa_io_global", "ciurlionis_fairy_tale_of_the_castle")
ARMS = {
    "look_zeros": {},
    "look_solid2": dict(texture_side=64, texture_start="solid", texture_start_strength=2.0),
    "look_solid4": dict(texture_side=64, texture_start="solid", texture_start_strength=4.0),
}


def register_arms() -> list[str]:
    """The arms as benchmark methods (a study's hook into the registry; the product's methods are unchanged)."""
    from mistyle.benchmark.methods import METHODS, Method
    from mistyle.look import LookSettings

    def arm(settings):
        def albedo(context, density, style):
            pipeline = context.pipeline(refine_steps=0, refine_path_steps=0)
            return pipeline.fit_look(density, style, look_settings=LookSettings(**settings)).stylize(density)

        return albedo

    for name, settings in ARMS.items():
        METHODS[name] = Method(name, "ablation", f"a look with {settings or 'the defaults'}", arm(settings), True)
    return list(ARMS)


def pairs() -> list:
    from mistyle.benchmark.splits import real_densities, split_pairs

    chosen = split_pairs("validation", list(DENSITIES), list(STYLES[:2]))
    real = {spec.name: spec for spec in real_densities()}
    chosen += [(real[name], style) for name, style in zip(REAL_DENSITIES, STYLES[1:])]
    return chosen


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--report-only", action="store_true")
    parser.add_argument("--out", default=str(OUT))
    args = parser.parse_args(argv)
    from mistyle.benchmark.runner import report, run

    arms = register_arms()
    if args.report_only:
        report(Path(args.out))
        return
    methods = arms + ["solid_texture", "tuned_noise", "uniform"]
    run(args.out, pairs(), methods, res=256, spp=64, denoise="oidn", split="validation", resume=True)


if __name__ == "__main__":
    main()
