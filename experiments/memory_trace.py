"""Where a large frame's memory goes: the default output of one frame, its resident memory sampled over
time and split by stage (#51).

The frame is ``bench_scale.density(side)`` (the bundled smoke resampled) in the demo's style, stylized
and path traced once as ``bench_scale`` does (``Pipeline.stylize``, then one 512^2 view at 64 spp,
denoised), in a process of its own with an empty Dr.Jit disk cache. A thread samples the process's
resident set (``VmRSS``) every quarter second; the stages are marked by wrapping the functions that
make them (the network's noise fields and forward pass, the colour match's fit, renders and
applications, the look's fit and its steps, the working copy of a grid longer than ``--working-size``
and its albedo brought back, the path trace). Above ``--limit-gb`` the process stops
itself (a 24 GB machine would otherwise kill it, or something else, when it runs out) and the row says
where.

    .venv/bin/python experiments/memory_trace.py --side 256                        # about 4 min on 2 cores
    .venv/bin/python experiments/memory_trace.py --side 512 --limit-gb 20            # stylized at 256^3
    .venv/bin/python experiments/memory_trace.py --side 512 --working-size 0 --scale-structures 0.5
    .venv/bin/python experiments/memory_trace.py --side 512 --command    # mistyle-render, writing its files

Appends a row to ``--out``/rows.jsonl (side, options, seconds and peak resident memory of each stage,
whether it finished) and writes the sampled trace to ``--out``/trace_<side>_<scale>_<working size>.txt
(not kept in the repository: the row holds each stage's seconds and peak) and the final image next to it
(.jpg).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "memory_trace"
sys.path.insert(0, str(ROOT / "experiments"))

from mistyle.resample import DEFAULT_WORKING_SIZE  # noqa: E402


def resident_gb() -> float:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS"):
                return int(line.split()[1]) / 2**20
    return float("nan")


class Trace:
    """Samples of (seconds, resident GB) and stage marks, written as they come (a stopped process keeps them)."""

    def __init__(self, path: Path, limit_gb: float):
        self.file, self.limit_gb, self.started = open(path, "w"), limit_gb, time.perf_counter()

    def write(self, text: str) -> None:
        self.file.write(f"{time.perf_counter() - self.started:.2f} {text}\n")
        self.file.flush()

    def sample_forever(self) -> None:
        while True:
            resident = resident_gb()
            self.write(f"rss {resident:.3f}")
            if resident > self.limit_gb:
                self.write(f"stopped above {self.limit_gb} GB")
                os._exit(3)
            time.sleep(0.25)

    def marked(self, name: str, function):
        def wrapper(*args, **kwargs):
            self.write(f"begin {name}")
            result = function(*args, **kwargs)
            self.write(f"end {name}")
            return result

        return wrapper


def mark_stages(trace: Trace) -> None:
    import mistyle.colour_match as colour_match
    import mistyle.look.fit as look_fit
    import mistyle.model.noise as noise
    import mistyle.model.skpn as skpn
    import mistyle.pipeline.chain as chain
    import mistyle.pipeline.frames as frames
    import mistyle.response as response

    noise._noise_fields = trace.marked("noise fields", noise._noise_fields)
    skpn.SKPN.forward = trace.marked("network forward", skpn.SKPN.forward)
    colour_match.fit_colour_match = trace.marked("colour match fit", colour_match.fit_colour_match)
    colour_match.ColourMatch.applied = trace.marked("colour match application", colour_match.ColourMatch.applied)
    response.albedo_renders = trace.marked("colour match renders", response.albedo_renders)
    chain.Pipeline.fit_look = trace.marked("look fit", chain.Pipeline.fit_look)
    look_fit._fit_steps = trace.marked("look fit steps", look_fit._fit_steps)
    chain.Pipeline.path_trace = trace.marked("path trace", chain.Pipeline.path_trace)
    frames.Frames.at_working_size = trace.marked("working copy", frames.Frames.at_working_size)
    frames.Frames.full_albedos = trace.marked("albedo to the full grid", frames.Frames.full_albedos)


def run_command(side: int, working_size: int, trace_path: Path, limit_gb: float) -> None:
    """``mistyle-render`` of the frame written as a ``.vol`` (256^2, 16 spp), its job's stages marked too:
    what the command holds while it writes its files."""
    trace = Trace(trace_path, limit_gb)
    threading.Thread(target=trace.sample_forever, daemon=True).start()
    mark_stages(trace)
    import mistyle.job.run as job_run

    for name in ("stylize_frames", "render_frames", "write_assets", "write_report"):
        setattr(job_run, name, trace.marked(name, getattr(job_run, name)))
    from bench_scale import STYLE, density

    from mistyle.files import write_vol
    from mistyle.render_final import main

    with tempfile.TemporaryDirectory(prefix="memory-trace-command-") as folder:
        write_vol(Path(folder) / "density.vol", density(side))
        trace.write("density made")
        options = ["--density", str(Path(folder) / "density.vol"), "--style", str(STYLE), "--out", f"{folder}/out"]
        options += ["--res", "256", "--spp", "16", "--working-size", str(working_size), "--quiet"]
        if main(options) != 0:
            raise SystemExit("mistyle-render failed")
        trace.write("finished")


def run_frame(side: int, scale_structures: float, working_size: int, trace_path: Path, limit_gb: float) -> None:
    trace = Trace(trace_path, limit_gb)
    threading.Thread(target=trace.sample_forever, daemon=True).start()
    mark_stages(trace)
    from bench_scale import STYLE, density

    from mistyle.files import write_jpeg
    from mistyle.pipeline import Pipeline, PipelineSettings, RenderSettings
    from mistyle.tone import display

    grid = density(side)
    trace.write("density made")
    render = RenderSettings(res=512, spp=64, denoise="oidn")
    settings = PipelineSettings(
        device="cpu", scale_structures=scale_structures, working_size=working_size, render=render
    )
    pipeline = Pipeline(settings)
    stylized = pipeline.stylize(grid, str(STYLE))
    images, _ = pipeline.path_trace(stylized.frames, [stylized.albedos[0]], pipeline.views()[:1])
    trace.write("finished")
    write_jpeg(trace_path.with_suffix(".jpg"), display(images[0]), srgb=False)


def summary(trace_path: Path) -> dict:
    """Per stage (first begin to its end, or to the last sample): seconds and peak resident GB."""
    samples, stages, open_stages, last = [], [], {}, 0.0
    for line in trace_path.read_text().splitlines():
        seconds, text = line.split(" ", 1)
        last = float(seconds)
        if text.startswith("rss "):
            samples.append((last, float(text.split()[1])))
        elif text.startswith("begin "):
            open_stages.setdefault(text[6:], []).append(last)
        elif text.startswith("end "):
            begin = open_stages[text[4:]].pop()
            stages.append((text[4:], begin, last))
    stages += [(name, begin, last) for name, begins in open_stages.items() for begin in begins]
    rows = []
    for name, begin, end in sorted(stages, key=lambda stage: stage[1]):
        inside = [gb for seconds, gb in samples if begin <= seconds <= end]
        rows.append(
            {"stage": name, "begin_s": begin, "seconds": end - begin, "peak_gb": max(inside) if inside else None}
        )
    text = trace_path.read_text()
    return {
        "stages": rows,
        "peak_gb": max(gb for _, gb in samples),
        "seconds": last,
        "finished": " finished" in text,
        "stopped": next((line.split(" ", 1)[1] for line in text.splitlines() if " stopped above " in line), None),
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--side", type=int, default=256)
    parser.add_argument("--scale-structures", type=float, default=1.0)
    parser.add_argument("--working-size", type=int, default=DEFAULT_WORKING_SIZE)
    parser.add_argument("--limit-gb", type=float, default=20.0)
    parser.add_argument("--out", default=str(OUT))
    parser.add_argument(
        "--command", action="store_true", help="trace mistyle-render on the frame as a .vol (256^2, 16 spp)"
    )
    parser.add_argument("--run", action="store_true", help=argparse.SUPPRESS)  # the frame, in this process
    parser.add_argument("--trace", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.run and args.command:
        run_command(args.side, args.working_size, Path(args.trace), args.limit_gb)
        return
    if args.run:
        run_frame(args.side, args.scale_structures, args.working_size, Path(args.trace), args.limit_gb)
        return
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    kind = "command_" if args.command else ""
    trace_path = out / f"trace_{kind}{args.side}_{args.scale_structures:g}_{args.working_size}.txt"
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="memory-trace-home-") as home:  # Dr.Jit's disk cache starts empty
        command = [sys.executable, __file__, "--run", "--side", str(args.side), "--trace", str(trace_path)]
        command += ["--scale-structures", str(args.scale_structures), "--limit-gb", str(args.limit_gb)]
        command += ["--working-size", str(args.working_size)] + (["--command"] if args.command else [])
        returncode = subprocess.run(command, cwd=ROOT, env={**os.environ, "HOME": home}).returncode
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    row = {
        "side": args.side,
        "scale_structures": args.scale_structures,
        "working_size": args.working_size,
        "command": args.command,
        "limit_gb": args.limit_gb,
        "returncode": returncode,
        "commit": commit.stdout.strip(),
        "load_before": load,
        **summary(trace_path),
    }
    with open(out / "rows.jsonl", "a") as rows:
        rows.write(json.dumps(row) + "\n")
    print(json.dumps(row, indent=1))


if __name__ == "__main__":
    main()
