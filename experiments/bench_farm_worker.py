"""What a farm worker's chunks cost after its first (#51 part 3): a warm process against a fresh one per chunk.

``mistyle-farm`` sends each chunk of frames to a Dask worker as ``farm.render_chunk``, which does what
``mistyle-render --look ... --frames a-b`` does (``job.render_look_chunk``) inside the worker's process.
A worker is one long-lived process, so what a chunk loads or compiles stays for its next chunk: the
pipeline with its network (``farm.worker_pipeline``), the path tracer's scene and its Dr.Jit kernels
(``pathtrace.SCENES``), torch's and Dr.Jit's own start-up. This measures it: a look is saved once
(``mistyle-render --save-look``), then the same chunks are rendered (a) one after another by
``farm.render_chunk`` in one process, as a worker does, and (b) each by a fresh ``python -m
mistyle.render_final`` process, as a farm that started a process per chunk would. Each chunk's seconds
from its call to its files; (b) includes the process's start. The density is the bundled smoke, moved
and scaled each frame (a new grid every frame, as ``bench_scale.py``'s sequence); ``--res``/``--spp`` as
the farm's options.

    .venv/bin/python experiments/bench_farm_worker.py               # results/bench_farm_worker/ (~5 min)
    .venv/bin/python experiments/bench_farm_worker.py --frames 6 --chunk 2 --res 64 --spp 4   # quick
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "experiments"))

OUT = ROOT / "results" / "bench_farm_worker"


def write_sequence(folder: Path, frames: int) -> Path:
    """``frames`` .vol files of the bundled smoke, each moved and scaled (``bench_scale``'s sequence)."""
    from bench_scale import density

    from mistyle.files import write_vol

    folder.mkdir(parents=True, exist_ok=True)
    for index in range(frames):
        write_vol(folder / f"frame_{index:04d}.vol", density(64, index))
    return folder


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=12)
    parser.add_argument("--chunk", type=int, default=3)
    parser.add_argument("--res", type=int, default=256)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--out", default=str(OUT))
    args = parser.parse_args(argv)
    from mistyle.farm import chunk_settings, frame_chunks, render_chunk

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    options = ["--res", str(args.res), "--spp", str(args.spp), "--turntable", "1"]
    with tempfile.TemporaryDirectory() as work:
        work = Path(work)
        density = write_sequence(work / "density", args.frames)
        look = work / "smoke.look"
        style = ROOT / "mistyle" / "data" / "heldout_styles" / "hokusai_great_wave.jpg"
        fitted = [sys.executable, "-m", "mistyle.render_final", "--density", str(density), "--style", str(style)]
        subprocess.run([*fitted, "--save-look", str(look), "--quiet"], check=True, cwd=ROOT)
        chunks = frame_chunks(args.frames, args.chunk)

        warm = []
        for first, last in chunks:
            started = time.perf_counter()
            result = render_chunk(
                look.read_bytes(), str(density), str(work / "warm"), first, last, *chunk_settings(options)
            )
            if "error" in result:
                raise SystemExit(f"chunk {first}-{last}: {result['error']}")
            warm.append(time.perf_counter() - started)

        fresh = []
        for first, last in chunks:
            chunk = ["--density", str(density), "--look", str(look), "--out", str(work / "fresh")]
            argv = [*chunk, "--frames", f"{first}-{last}", "--quiet", *options]  # the command a farm task runs
            started = time.perf_counter()
            subprocess.run([sys.executable, "-m", "mistyle.render_final", *argv], check=True, cwd=ROOT)
            fresh.append(time.perf_counter() - started)

    per_frame = [seconds / args.chunk for seconds in warm[1:]]
    record = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
        "load_1min_at_end": os.getloadavg()[0],
        "frames": args.frames,
        "chunk": args.chunk,
        "res": args.res,
        "spp": args.spp,
        "warm_process_chunk_seconds": warm,
        "fresh_process_chunk_seconds": fresh,
        "warm_seconds_per_frame_after_first_chunk": statistics.median(per_frame) if per_frame else None,
        "fresh_seconds_per_frame": statistics.median(fresh) / args.chunk,
        "warm_over_fresh_after_first_chunk": statistics.median(warm[1:]) / statistics.median(fresh[1:])
        if len(chunks) > 1
        else None,
    }
    (out / "result.json").write_text(json.dumps(record, indent=2) + "\n")
    print(json.dumps(record, indent=2))


if __name__ == "__main__":
    main()
