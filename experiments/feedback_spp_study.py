"""Does the colour match's feedback render, at 4 paths a pixel, dull the colours users see? (#48)

The colour match's last step (``colour_match.fit_colour_match``, step 4) path traces the matched albedo
from 8 views at 32^2 with ``FEEDBACK_SPP`` = 4 paths a pixel and carries that render's foreground
colours onto the style's. Those settings were chosen in #13, when the benchmark scored 128^2 renders at
16 spp without a denoiser; users see 256^2 at 64 spp, denoised. At 4 spp a thin medium's fringe pixels
are either black (no path scattered: out of the foreground) or sparse bright samples, so the feedback
sees a foreground brighter and wider than the converged render's, and its correction darkens and
narrows the colours. A probe on three thin-smoke validation pairs (the default output, scored as users
see it) agreed: at 32^2 the render came out 4-6 L* darker than the style at 4 spp and 2-4 at 64 spp,
RGB SWD 0.61-0.83x; at 128^2 with 4 spp no gain (the samples, not the resolution, matter).

Arms, the default output with the feedback render at 32^2 from 8 views as now and:
* ``feedback16``: 16 paths a pixel (+0.15 s a colour match at 64^3 on this CPU);
* ``feedback64``: 64 paths a pixel, what users' renders have (+0.8 s a colour match).
Each arm changes the one colour match both stages use (the network's and the look's); tuned noise +
colour match keeps the match as it is in this run. An adopted arm is the product's colour match, so the
baselines that share it are scored again with it on the held-out and real splits.

Pairs: the validation split's two 64^3 densities (thin smoke and dense cloud) with all 14 validation
styles (28 pairs); scoring as users see it (256^2, 64 spp, OIDN), the default and tuned noise in the
same run.

Rule written before the rows: among the arms whose median fit time is at most 1.5x the default's, whose
median patch SWD is at most 1.02x the default's and whose count of pairs closer in structure than tuned
noise is at least the default's minus 1, the arm with the lowest median RGB SWD replaces the default's
feedback samples if that median is at most 0.95x the default's and its median hue coverage is at least
the default's; a tie goes to fewer samples.

    .venv/bin/python experiments/feedback_spp_study.py              # about 30 min on 2 cores
    .venv/bin/python experiments/feedback_spp_study.py --report-only
    .venv/bin/python experiments/feedback_spp_study.py --cost    # the feedback render's time, into cost.jsonl
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "experiments"))

OUT = ROOT / "results" / "feedback_spp_study"
ARMS = {"feedback16": 16, "feedback64": 64}
FROZEN_AT = "1dd6867"
"""The last commit whose default feedback takes 4 paths a pixel, the arms' baseline: the study's rows ran
there (``--report-only`` and ``--cost`` run anywhere)."""


def register_arms() -> list[str]:
    """The arms as benchmark methods (a study's hook into the registry; the product's methods are unchanged)."""
    from mistyle import colour_match
    from mistyle.benchmark.methods import METHODS, Method

    default = METHODS["default"]

    def arm(samples):
        def albedo(context, density, style):
            kept, colour_match.FEEDBACK_SPP = colour_match.FEEDBACK_SPP, samples
            try:
                return default.albedo(context, density, style)
            finally:
                colour_match.FEEDBACK_SPP = kept

        return albedo

    for name, samples in ARMS.items():
        description = f"the default output with the colour match's feedback render at {samples} paths a pixel"
        METHODS[name] = Method(name, "ablation", description, arm(samples), True)
    return list(ARMS)


def pairs() -> list:
    from mistyle.benchmark.splits import split_pairs

    return split_pairs("validation", ["val_smoke64", "val_pyroclastic64"])


def feedback_cost(sides=(64, 128), samples=(4, 16, 64), repeats: int = 3) -> list[dict]:
    """Seconds of the feedback render (``FEEDBACK_VIEWS`` views at ``FEEDBACK_RES``^2, one launch) of the
    bundled smoke resampled to each side, at each number of paths a pixel: the median of ``repeats``
    after one render that compiles."""
    import os
    import time

    import numpy as np
    from bench_scale import density as resampled_smoke

    from mistyle import colour_match
    from mistyle.response import albedo_renders
    from mistyle.scenes import CameraPath
    from mistyle.stylizer import Stylizer

    stylizer = Stylizer(None)
    render = stylizer.config.render
    views = CameraPath(distance=render.camera_distance).turntable(colour_match.FEEDBACK_VIEWS)
    rows = []
    for side in sides:
        density = resampled_smoke(side)
        albedo = np.full(density.shape + (3,), 0.7, np.float32)

        def once(spp, density=density, albedo=albedo):
            started = time.perf_counter()
            albedo_renders(
                density,
                stylizer.density_scale,
                render.radiance,
                views,
                [albedo],
                res=colour_match.FEEDBACK_RES,
                spp=spp,
                batch=True,
            )
            return time.perf_counter() - started

        once(samples[0])
        for spp in samples:
            seconds = float(np.median([once(spp) for _ in range(repeats)]))
            rows.append({"side": side, "spp": spp, "seconds": seconds, "load_1min": os.getloadavg()[0]})
    return rows


def main(argv=None) -> None:
    import json

    from study import arm_study, require_frozen_commit

    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--cost"]:
        rows = feedback_cost()
        (OUT / "cost.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
        print("\n".join(json.dumps(row) for row in rows))
        return
    if "--report-only" not in argv:
        require_frozen_commit(__file__, FROZEN_AT)
    arm_study(__doc__.splitlines()[0], OUT, register_arms, pairs, argv, baselines=("tuned_noise",))


if __name__ == "__main__":
    main()
