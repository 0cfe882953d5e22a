"""The colour match's fit and application on the network's albedo of the bundled smoke at one size: what
the network stage of the default output spends on it (#51).

    .venv/bin/python experiments/bench_colour_match.py --side 256             # prints one JSON row
    PYTHONPATH=DIR .venv/bin/python experiments/bench_colour_match.py ...     # another commit's code (a worktree)

The density is ``bench_scale.density`` (the bundled smoke resampled); the albedo the shipped network's
for the demo's style. Times: the grey response, the fit (with its feedback render) and the application
to the fitted albedo, after one untimed round that compiles the renders' kernels; the most memory NumPy
held at once over the fit and the application beyond the inputs (``numpy_peak_gb``: a last round under
``tracemalloc``, which NumPy reports its arrays to); and a digest of the matched albedo, so two commits'
rows show whether their albedos are the same bit for bit.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
import tracemalloc
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--side", type=int, default=128)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--label", default="this checkout", help="whose code, e.g. a commit")
    args = parser.parse_args(argv)

    import numpy as np
    from bench_scale import STYLE, density

    from mistyle import colour_match
    from mistyle.pipeline import Pipeline, PipelineSettings
    from mistyle.stylizer import Style

    pipeline = Pipeline(PipelineSettings(device="cpu"))
    grid = density(args.side)
    style = Style.of(str(STYLE), [])
    albedo = pipeline.stylizer(
        grid,
        style,
        1.0,
        notes=[],
        match_colours=False,
        density_scale=pipeline.density_scale,
        camera_distance=pipeline.camera_distance,
    )
    scene = {
        "density_scale": pipeline.density_scale,
        "radiance": pipeline.stylizer.config.render.radiance,
        "camera_distance": pipeline.camera_distance,
    }
    rounds = []
    for _ in range(args.repeats + 1):
        started = time.perf_counter()
        response = colour_match.grey_response(grid, **scene)
        responded = time.perf_counter()
        match = colour_match.fit_colour_match(albedo, grid, style.target, response=response, **scene)
        fitted = time.perf_counter()
        matched = match.apply(albedo, grid)
        rounds.append(
            {"response_s": responded - started, "fit_s": fitted - responded, "apply_s": time.perf_counter() - fitted}
        )
    timed = rounds[1:]
    tracemalloc.start()
    colour_match.fit_colour_match(albedo, grid, style.target, response=response, **scene).apply(albedo, grid)
    numpy_peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    print(
        json.dumps(
            {
                "side": args.side,
                "code": args.label,
                "medium_voxels": int((grid > 0).sum()),
                **{key: float(np.median([r[key] for r in timed])) for key in timed[0]},
                "numpy_peak_gb": numpy_peak / 2**30,
                "matched_sha256": hashlib.sha256(np.ascontiguousarray(matched).tobytes()).hexdigest()[:16],
            }
        )
    )


if __name__ == "__main__":
    main()
