"""Final path tracing of sparse smoke: one medium in the box vs the medium cut into bricks.

``volpath`` renders the same stylized smoke in two ways, three times each with different seeds:
  * ``plain``: one ``heterogeneous`` medium in the box (one global majorant);
  * ``bricks``: ``mistyle.scenes.bricks`` (empty bricks are vacuum, the others grouped into
    majorant levels, each level its own medium).

From the seeds of each, the per-pixel variance of one render (``mean((a - b)^2) / 2`` over pairs), so
the time to equal noise is ``seconds * variance`` (median seconds) and the speed-up at equal noise is
``(seconds_plain * var_plain) / (seconds_bricks * var_bricks)``. ``mean_z`` is the difference of
the two images' means over its standard error: the two are the same estimate (|z| below ~3).

Densities: ``examples/smoke_64.vol`` (41% of voxels occupied), and the same smoke resampled to 128^3.
Albedo: a colour-noise field (``data.procedural.colour_noise_albedo``). Light: the training light.
At 128^2 the fixed cost of a render (tracing the kernel, the film) takes a larger share and the
speed-up is ~10% lower.

Prints one JSON line per density (and per brick size with ``--sweep``).

    python experiments/bench_pathtrace.py            # 256^2 images, 64 spp (render_final's defaults), both densities
    python experiments/bench_pathtrace.py --quick    # 64^2, 16 spp, 64^3 only
    python experiments/bench_pathtrace.py --sweep    # brick sizes 4 / 8 / 16 and 1 or 4 levels
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "smoke_64.vol"


def render_repeats(scene, spp: int, repeats: int = 3) -> tuple[np.ndarray, float, float]:
    """``repeats`` renders of ``scene`` with different seeds: ``(mean image, variance of one render, median
    seconds of one)``; the variance is the mean over pairs of ``mean((a - b)^2) / 2``."""
    import mitsuba as mi

    mi.render(scene, spp=1, seed=99)  # compile
    images, seconds = [], []
    for seed in range(1, repeats + 1):
        start = time.perf_counter()
        images.append(np.asarray(mi.render(scene, spp=spp, seed=seed * 7919))[..., :3])
        seconds.append(time.perf_counter() - start)
    pairs = [(a, b) for i, a in enumerate(images) for b in images[i + 1 :]]
    variance = float(np.mean([np.mean((a - b) ** 2) / 2 for a, b in pairs]))
    return np.mean(images, axis=0), variance, float(np.median(seconds))


def compare(density: np.ndarray, image: int, spp: int, configurations: list[tuple[int, int]]) -> list[dict]:
    """One JSON-ready record per ``(brick, levels)`` against the plain medium, all in one run."""
    from mistyle.backend import use_variant
    from mistyle.conventions import DEFAULT_DENSITY_SCALE, HELD_OUT_VIEW
    from mistyle.data.procedural import colour_noise_albedo
    from mistyle.scenes import CameraPath, pathtraced_scene
    from mistyle.scenes.bricks import brick_levels, bricked_media

    mi = use_variant("cpu")
    albedo = colour_noise_albedo(density.shape, seed=3)
    views = [CameraPath().view(HELD_OUT_VIEW)]

    def scene(brick: int, levels: int):
        entries = pathtraced_scene(density, albedo, views, res=image, density_scale=DEFAULT_DENSITY_SCALE, spp=spp)
        if brick:
            del entries["medium_box"]
            entries.update(bricked_media(density, DEFAULT_DENSITY_SCALE, albedo, brick, levels))
        return mi.load_dict(entries)

    plain, plain_var, plain_seconds = render_repeats(scene(0, 0), spp)
    records = []
    for brick, levels in configurations:
        start = time.perf_counter()
        bricked_scene = scene(brick, levels)
        build_seconds = time.perf_counter() - start
        image_b, var_b, seconds_b = render_repeats(bricked_scene, spp)
        level, _ = brick_levels(density, brick, levels)
        standard_error = np.sqrt((plain_var + var_b) / 3 / plain.size)  # of the difference of two 3-render means
        records.append(
            {
                "figure": "pathtrace_equal_noise",
                "shape": list(density.shape),
                "occupied_fraction": float((density > 0).mean()),
                "image": image,
                "spp": spp,
                "brick": brick,
                "levels": levels,
                "bricks_by_level": np.bincount(
                    level.ravel() + 1, minlength=levels + 1
                ).tolist(),  # [empty, level 0, ...]
                "plain_seconds": plain_seconds,
                "bricks_seconds": seconds_b,
                "bricks_build_seconds": build_seconds,
                "plain_variance": plain_var,
                "bricks_variance": var_b,
                "time_ratio": plain_seconds / seconds_b,
                "equal_noise_speedup": (plain_seconds * plain_var) / (seconds_b * var_b),
                "mean_z": float((image_b.mean() - plain.mean()) / standard_error),
                "machine": machine(),
            }
        )
    return records


def machine() -> dict:
    return {
        "cpu": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "load_avg_1m": round(os.getloadavg()[0], 2),
        "date": time.strftime("%Y-%m-%d"),
    }


def run(quick: bool = False, sweep: bool = False) -> list[dict]:
    """The benchmark's records (``bench_all`` calls this)."""
    from mistyle.backend import use_variant
    from mistyle.files import load_density
    from mistyle.integrators.inscatter import resample_trilinear
    from mistyle.scenes.bricks import DEFAULT_BRICK, DEFAULT_LEVELS

    use_variant("cpu")
    smoke = load_density(EXAMPLE)
    densities = [smoke] if quick else [smoke, resample_trilinear(smoke, 2)]
    configurations = [(DEFAULT_BRICK, DEFAULT_LEVELS)]
    if sweep:
        configurations = [(b, lv) for b in (4, 8, 16) for lv in (1, DEFAULT_LEVELS)]
    image, spp = (64, 16) if quick else (256, 64)  # render_final's defaults
    return [record for density in densities for record in compare(density, image, spp, configurations)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--sweep", action="store_true")
    args = parser.parse_args()
    for record in run(args.quick, args.sweep):
        print(json.dumps(record), flush=True)


if __name__ == "__main__":
    main()
