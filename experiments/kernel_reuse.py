"""Kernels compiled per frame of a path-traced sequence (issue #51, item 1: compiled once per run).

Path-traces ``--frames`` different 64^3 frames in one process through ``mistyle.pathtrace.path_trace``, as
a sequence does (``Pipeline.path_trace``: frame ``i`` from view ``i`` of a turntable), and reports per
frame the wall time and Dr.Jit's kernels: launched, new to the process (a hash not launched before) and
compiled by LLVM (not found in Dr.Jit's on-disk cache either), with their codegen and compile times.
The frames are the bundled smoke rolled along x and scaled (new grids, majorants and brick layouts each
frame), each with its own colour-noise albedo. Three passes over the frames:

* ``first``: the sequence in order, as a render runs it (frame 0 compiles what a frame needs);
* ``again``: the same frames once more (every kernel a frame needs has been compiled once);
* ``fresh``: each frame with the kept scene released first (``pathtrace.release_scenes``, code that
  has it only): a scene loaded anew, whose image each cached frame must equal bit for bit.

Configurations: one 64^2 pass at 4 spp (the issue's measurement), 16 frozen passes (64 spp in passes of
4: ``render_passes``' ``dr.freeze``), and the medium without majorant bricks (``bricks=0``). And the fast
layer for comparison (its Ls grid, ``integrators.prepare_density``, and one ``bridge_torch.render_views``
image a frame): passes ``first`` and ``again`` only.

Each code runs in its own process with an empty Dr.Jit disk cache (``$HOME/.drjit`` in a temporary
home), so a kernel is compiled the first time the process needs it and never found from an earlier run.
``--baseline DIR`` (other code, e.g. ``git archive HEAD mistyle | tar -x -C DIR`` for a temporary DIR) runs that code
first, on the same machine in the same run; its package is imported from ``DIR`` (``PYTHONPATH``).

    .venv/bin/python experiments/kernel_reuse.py --baseline DIR   # results/kernel_reuse/

Writes ``runs.json`` (every frame of every pass) and ``table.md`` under ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CONFIGS = {
    "1 pass, 4 spp": {"res": 64, "spp": 4},
    "16 frozen passes, 64 spp": {"res": 64, "spp": 64, "max_pass_samples": 64 * 64 * 4},
    "no bricks, 4 spp": {"res": 64, "spp": 4, "bricks": 0},
}
FAST_LAYER = "fast layer: Ls grid + 64^2 image"


def frames(count: int, first: int = 0):
    """``count`` different ``(density (64, 64, 64), albedo (64, 64, 64, 3))`` frames of the bundled smoke,
    from frame ``first`` of the series (rolled by 5 voxels and 10% denser a frame, its own albedo)."""
    import numpy as np

    from mistyle.data.procedural import colour_noise_albedo
    from mistyle.files import read_vol

    smoke = read_vol(REPO / "examples" / "smoke_64.vol").astype(np.float32)
    return [
        (np.roll(smoke, 5 * i, axis=2) * np.float32(1.0 + 0.1 * i), colour_noise_albedo(smoke.shape, seed=i))
        for i in range(first, first + count)
    ]


def kernels(seen: set) -> dict:
    """The JIT kernels launched since the history was last emptied: how many, how many new to this
    process (``seen``, updated), how many of those LLVM compiled, and their codegen/compile times."""
    import drjit as dr

    launched = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    new = [k for k in launched if k["hash"] not in seen]
    seen.update(k["hash"] for k in launched)
    return {
        "launches": len(launched),
        "new_kernels": len({k["hash"] for k in new}),
        "compiled": len({k["hash"] for k in new if not k.get("cache_disk", False)}),
        "codegen_ms": round(sum(k.get("codegen_time", 0.0) for k in launched), 1),
        "backend_ms": round(sum(k.get("backend_time", 0.0) for k in launched), 1),
    }


def worker(count: int) -> dict:
    """Every configuration's passes in this process: ``{"records": [...], "mistyle": path}``."""
    import drjit as dr
    import numpy as np

    import mistyle
    from mistyle import pathtrace
    from mistyle.scenes import CameraPath

    views = CameraPath().turntable(count)
    seen: set[str] = set()
    records = []
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    passes = ["first", "again"] + (["fresh"] if hasattr(pathtrace, "release_scenes") else [])
    for number, (name, options) in enumerate(CONFIGS.items()):
        # Frames of their own: a configuration must not find kernels compiled for another's frames.
        data = frames(count, first=number * count)
        images = {}
        for run in passes:
            for index, (density, albedo) in enumerate(data):
                if run == "fresh":
                    pathtrace.release_scenes()
                dr.kernel_history()  # empties the history
                started = time.perf_counter()
                (image,), _ = pathtrace.path_trace(density, albedo, [views[index]], **options)
                wall = time.perf_counter() - started
                first = images.setdefault(index, image)
                records.append(
                    {
                        "config": name,
                        "pass": run,
                        "frame": index,
                        "wall_s": round(wall, 4),
                        **kernels(seen),
                        "max_diff_vs_first_pass": float(np.abs(image - first).max()),
                        "mean": float(image.mean()),
                    }
                )
    records += fast_layer(views, frames(count, first=len(CONFIGS) * count), seen)
    return {"records": records, "mistyle": Path(mistyle.__file__).parent.name}  # no machine paths in results


def fast_layer(views, data, seen: set) -> list[dict]:
    """The same for the fast layer (not changed by the path tracer's fix): each frame's Ls grid
    (``integrators.prepare_density``) and a 64^2 image (``bridge_torch.render_views``), twice over."""
    import drjit as dr
    import numpy as np
    import torch

    from mistyle.bridge_torch import render_views
    from mistyle.integrators import prepare_density

    records = []
    images = {}
    for run in ("first", "again"):
        for index, (density, albedo) in enumerate(data):
            dr.kernel_history()
            started = time.perf_counter()
            prepared = prepare_density(density, 20.0)
            with torch.no_grad():
                image = render_views(
                    torch.from_numpy(albedo).permute(3, 0, 1, 2).contiguous(), prepared, [views[index]], 64
                )
            wall = time.perf_counter() - started
            image = image.numpy()
            first = images.setdefault(index, image)
            records.append(
                {
                    "config": FAST_LAYER,
                    "pass": run,
                    "frame": index,
                    "wall_s": round(wall, 4),
                    **kernels(seen),
                    "max_diff_vs_first_pass": float(np.abs(image - first).max()),
                    "mean": float(image.mean()),
                }
            )
    return records


def run_code(label: str, package_root: Path, count: int) -> dict:
    """``worker`` in a new process importing mistyle from ``package_root``, with an empty kernel cache."""
    with tempfile.TemporaryDirectory() as home:
        env = {**os.environ, "HOME": home, "PYTHONPATH": str(package_root)}  # Dr.Jit caches under $HOME/.drjit
        load = os.getloadavg()[0]
        result = subprocess.run(
            [sys.executable, __file__, "--worker", "--frames", str(count)],
            env=env,
            cwd=REPO,
            capture_output=True,
            text=True,
        )
    if result.returncode:
        raise RuntimeError(f"{label} failed:\n{result.stderr[-3000:]}")
    out = json.loads(result.stdout.strip().splitlines()[-1])
    return {"code": label, "root": Path(package_root).name, "load_before": load, **out}


def describe(root: Path) -> str:
    """The commit of the checkout at ``root`` and whether its tree has changes, else the folder."""
    try:
        commit = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=root, capture_output=True, text=True)
        status = subprocess.run(["git", "status", "--porcelain", "mistyle"], cwd=root, capture_output=True, text=True)
    except OSError:
        return str(root)
    if commit.returncode:
        return str(root)
    return commit.stdout.strip() + ("+changes" if status.stdout.strip() else "")


def machine() -> str:
    lines = Path("/proc/cpuinfo").read_text().splitlines() if Path("/proc/cpuinfo").exists() else []
    model = next((line.split(":", 1)[1].strip() for line in lines if "model name" in line), platform.processor())
    return f"{model}, {os.cpu_count()} cores visible"


def table(runs: list[dict], command: str, note: str) -> str:
    """``table.md``: per code, configuration and pass, each frame's seconds and kernels compiled."""
    lines = [
        "# Kernels compiled per frame of a path-traced sequence (issue #51, item 1)",
        "",
        f"Machine: {machine()}; {note}. Each code in its own process with an empty Dr.Jit disk cache; "
        "load average (1 min) before each: "
        + ", ".join(f"{run['code']} {run['load_before']:.2f}" for run in runs)
        + ".",
        "",
        "Per configuration and pass, frame by frame: the wall seconds of `path_trace` and the kernels LLVM "
        "compiled. `first`: the sequence in order; `again`: the same frames once more; `fresh`: the kept scene "
        "released before each frame (a scene loaded anew). Max diff: the largest difference of any pixel from "
        "the same frame's first-pass image (0: bit for bit).",
        "",
        "| code | configuration | pass | seconds per frame | compiled per frame | launches a frame | max diff |",
        "|---|---|---|---|---|---|---|",
    ]
    for run in runs:
        for name in [*CONFIGS, FAST_LAYER]:
            for which in ("first", "again", "fresh"):
                rows = [r for r in run["records"] if r["config"] == name and r["pass"] == which]
                if not rows:
                    continue
                seconds = ", ".join(f"{r['wall_s']:.2f}" for r in rows)
                lines.append(
                    f"| {run['code']} | {name} | {which} | {seconds} | "
                    f"{', '.join(str(r['compiled']) for r in rows)} | {rows[-1]['launches']} | "
                    f"{max(r['max_diff_vs_first_pass'] for r in rows):.3g} |"
                )
    lines += ["", f"`{command}`", ""]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=4)
    parser.add_argument("--baseline", type=Path, default=None, help="other code's root (its mistyle/ inside)")
    parser.add_argument("--baseline-name", default=None, help="what the baseline is, e.g. 'HEAD 1a2b3c4'")
    parser.add_argument("--out", type=Path, default=REPO / "results" / "kernel_reuse")
    parser.add_argument("--note", default="", help="the machine's load, e.g. 'a benchmark running on both cores'")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(worker(args.frames)))
        return
    runs = []
    if args.baseline is not None:
        label = args.baseline_name or describe(args.baseline)
        runs.append(run_code(f"baseline {label}", args.baseline.resolve(), args.frames))
    runs.append(run_code(f"this {describe(REPO)}", REPO, args.frames))
    args.out.mkdir(parents=True, exist_ok=True)
    command = "python experiments/kernel_reuse.py" + (" --baseline DIR" if args.baseline else "")
    meta = {"machine": machine(), "note": args.note, "frames": args.frames, "configs": CONFIGS, "command": command}
    (args.out / "runs.json").write_text(json.dumps({**meta, "runs": runs}, indent=1) + "\n")
    (args.out / "table.md").write_text(table(runs, command, args.note or "load as given"))
    print((args.out / "table.md").read_text())


if __name__ == "__main__":
    main()
