"""Where a look's fit step spends its time: the parts of ``look.fit_look``'s loop, in milliseconds a step.

Fits the default look (``LookSettings()``, ``--steps`` steps) on the bundled 64^3 smoke and style in a
fresh process, ``--runs`` times, with a timer around each part of the step:

* ``albedo``: the look's albedo of the key frame (``look.frame_albedo``: the head's convolution, the
  texture, tanh, uncrop),
* ``white render``: a render of a white albedo for the body mask (the code before 2026-12-03 ran one
  a step; the white views now come with the albedo's render, ``render_views(..., white=True)``),
* ``render``: the fast layer's forward render of the albedo, ``mask``: ``objective.masks.body_mask``,
* ``objective``: the sliced objective's forward pass, ``tv``: the TV term,
* ``backward``: the whole backward pass (the layer's adjoint, the head's and the objective's),
* ``optimizer``: Adam's step; ``setup``: the rest of the fit (the key frame's features, Ls grid,
  the style's targets, the colour match fitted after the steps).

The first fit of a process compiles Dr.Jit's kernels (or reads them from its cache), so one fit of 2
steps runs before the timed ones. ``--baseline DIR`` (a checkout of other code) runs the same in that
checkout, alternating with this one, and the table gives the ratios of the medians (this / baseline).

    python experiments/profile_look_step.py --runs 2 --baseline ../before --out results/profile_look_step

Writes ``rows.jsonl`` and ``table.md`` under ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PARTS = ("albedo", "white render", "render", "mask", "objective", "tv", "backward", "optimizer")


def profile(steps: int) -> dict:
    """One timed fit in this process: seconds per part (``PARTS``), the fit's and its setup's seconds."""
    import time
    from collections import defaultdict

    import torch

    import mistyle.adam as adam
    import mistyle.bridge_torch as bridge
    import mistyle.look as look
    import mistyle.objective.losses as losses
    import mistyle.objective.masks as masks
    import mistyle.objective.style as style
    from mistyle.files import read_vol
    from mistyle.stylizer import Stylizer

    seconds: dict[str, float] = defaultdict(float)

    def timed(part, function):
        def wrapper(*args, **kwargs):
            started = time.perf_counter()
            out = function(*args, **kwargs)
            seconds[part] += time.perf_counter() - started
            return out

        return wrapper

    render_views = bridge.render_views

    def render(albedo, *args, **kwargs):
        part = "render" if albedo.requires_grad else "white render"
        return timed(part, render_views)(albedo, *args, **kwargs)

    bridge.render_views = render
    masks.body_mask = timed("mask", masks.body_mask)
    losses.tv_loss = timed("tv", losses.tv_loss)
    style.SlicedObjective.loss = timed("objective", style.SlicedObjective.loss)
    adam.Adam.step = timed("optimizer", adam.Adam.step)
    look.frame_albedo = timed("albedo", look.frame_albedo)
    torch.Tensor.backward = timed("backward", torch.Tensor.backward)

    stylizer = Stylizer()
    density = read_vol(REPO / "examples" / "smoke_64.vol")
    style_path = REPO / "examples" / "style_marble.png"
    look.fit_look(stylizer, [density], style_path, settings=look.LookSettings(steps=2))  # compiles the kernels
    seconds.clear()
    started = time.perf_counter()
    look.fit_look(stylizer, [density], style_path, settings=look.LookSettings(steps=steps))
    fit = time.perf_counter() - started
    # frame_albedo also runs once after the steps (for the colour match): its time is shared among the steps.
    per_step = {part: seconds[part] / steps for part in PARTS}
    return {"steps": steps, "fit_seconds": fit, "setup_seconds": fit - sum(per_step.values()) * steps, **per_step}


def run_in(checkout: Path, steps: int) -> dict:
    """``profile`` in a fresh process on ``checkout``'s code."""
    env = {**os.environ, "PYTHONPATH": str(checkout)}
    done = subprocess.run(
        [sys.executable, str(Path(__file__).resolve()), "--child", str(steps)],
        cwd=checkout,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def write_table(out: Path, rows: list[dict]) -> None:
    codes = list(dict.fromkeys(row["code"] for row in rows))
    header = ["run", "code", "fit s", "setup s"] + [f"{part} ms" for part in PARTS] + ["step ms", "load"]
    lines = [
        f"A look's fit on the bundled 64^3 smoke and style (`LookSettings()`, {rows[0]['steps']} steps), "
        "milliseconds a step per part of the loop and seconds for the whole fit; 2 cores, load average "
        "(1 min) at the end of each run.",
        "",
        "| " + " | ".join(header) + " |",
        "|" + "---|" * len(header),
    ]

    def step_ms(row):
        return 1000 * sum(row[part] for part in PARTS)

    for row in rows:
        cells = [
            str(row["run"]),
            f"{row['code']} {row['commit']}",
            f"{row['fit_seconds']:.1f}",
            f"{row['setup_seconds']:.1f}",
        ]
        cells += [f"{1000 * row[part]:.1f}" for part in PARTS] + [f"{step_ms(row):.0f}", f"{row['load_average']:.1f}"]
        lines.append("| " + " | ".join(cells) + " |")
    if len(codes) == 2:
        mine, base = ([row for row in rows if row["code"] == code] for code in ("this", "baseline"))

        def ratio(value):
            before = statistics.median(value(row) for row in base)
            return f"{statistics.median(value(row) for row in mine) / before:.2f}" if before > 0 else "-"

        cells = [
            "ratio of medians",
            "this / baseline",
            ratio(lambda r: r["fit_seconds"]),
            ratio(lambda r: r["setup_seconds"]),
        ]
        cells += [ratio(lambda r, part=part: r[part]) for part in PARTS] + [ratio(step_ms), ""]
        lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        f"`python experiments/profile_look_step.py --runs {max(r['run'] for r in rows) + 1}"
        + (" --baseline DIR`" if len(codes) == 2 else "`"),
    ]
    (out / "table.md").write_text("\n".join(lines) + "\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="results/profile_look_step")
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--baseline", type=Path, default=None, help="another checkout, run before each run of this one")
    parser.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        print(json.dumps(profile(args.child)))
        return
    from mistyle.benchmark.runner import code_commit

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for run in range(args.runs):
        checkouts = ([("baseline", args.baseline.resolve())] if args.baseline else []) + [("this", REPO)]
        for code, checkout in checkouts:
            row = {"run": run, "code": code, "commit": code_commit(checkout), **run_in(checkout, args.steps)}
            row["load_average"] = os.getloadavg()[0]
            rows.append(row)
            print(json.dumps(row), flush=True)
    (out / "rows.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    write_table(out, rows)


if __name__ == "__main__":
    main()
