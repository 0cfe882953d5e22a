"""The learning curve of a training run: a table (JSON lines) and a PNG chart from its metrics.jsonl.

    python experiments/learning_curve.py runs/sliced2 --out results/learning_curve/learning_curve_sliced.png

Rows: the training loss averaged over windows of ``--window`` steps, with the validation metrics of
the evaluations in that window (held-out plumes and styles, fast-layer renders): ``val_swd``, and
where the run logged them the fidelity benchmark's ``val_rgb_swd``, ``val_patch_swd`` and
``val_hue_coverage``. The summary line gives each metric at the start, its best and its end, and
``next_doubling``: a power law ``m = a * step^b`` fitted to the evaluations of the second half of the
run, read at twice the last step, as the factor it predicts for each metric (for the distances,
< 1 means better) -- what the next doubling of training steps would buy if the trend held.

The chart has one panel per metric against the step (the loss in black, evaluations in red).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from mistyle.pages import EXPERIMENTS_TITLE, write_index

VAL_METRICS = ("val_swd", "val_rgb_swd", "val_patch_swd", "val_hue_coverage")


def next_doubling(evals: list[tuple[int, float]]) -> float | None:
    """Factor by which a power law fitted to the second half of ``(step, value)`` changes from the last step
    to twice it."""
    last = max(step for step, _ in evals)
    late = [(s, v) for s, v in evals if s >= last / 2 and s > 0 and v > 0]
    if len(late) < 3:
        return None
    slope = np.polyfit(np.log([s for s, _ in late]), np.log([v for _, v in late]), 1)[0]
    return float(2.0**slope)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path)
    parser.add_argument("--window", type=int, default=250)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    records = [json.loads(line) for line in (args.run / "metrics.jsonl").read_text().splitlines() if line.strip()]
    train = [(r["step"], r["loss"], r["loss_hist"]) for r in records if "loss" in r]
    metrics = [key for key in VAL_METRICS if any(key in r for r in records)]
    evals = {key: [(r["step"], r[key]) for r in records if key in r] for key in metrics}
    steps = np.array([s for s, _, _ in train])
    losses = np.array([loss for _, loss, _ in train])
    for start in range(0, int(steps.max()), args.window):
        inside = (steps > start) & (steps <= start + args.window)
        row = {
            "steps": f"{start + 1}-{start + args.window}",
            "loss": float(losses[inside].mean()),
            "loss_hist": float(np.mean([h for (s, _, h) in train if start < s <= start + args.window])),
        }
        for key in metrics:
            row[key] = [round(v, 4) for s, v in evals[key] if start < s <= start + args.window] or None
        print(json.dumps(row))
    summary = {
        "last_step": int(steps.max()),
        "seconds": next(r["seconds"] for r in reversed(records) if "seconds" in r),
        "peak_memory_mb": max(r.get("peak_memory_mb", 0) for r in records),
    }
    for key in metrics:
        values = [v for _, v in evals[key]]
        best = max(values) if key == "val_hue_coverage" else min(values)
        summary[key] = {
            "start": round(values[0], 4),
            "best": round(best, 4),
            "end": round(values[-1], 4),
            "best_step": evals[key][values.index(best)][0],
            "next_doubling": next_doubling(evals[key]),
        }
    print(json.dumps(summary))
    if args.out:
        chart(args.out, steps, losses, evals)
        write_index(args.out.parent, EXPERIMENTS_TITLE)
        print(f"wrote {args.out} and {args.out.parent / 'index.html'}")


def chart(path: Path, steps, losses, evals: dict, width: int = 720, panel: int = 150) -> None:
    from PIL import Image, ImageDraw

    margin, top = 48, 22
    panels = [("loss (mean of 25 steps)", None)] + list(evals.items())
    image = Image.new("RGB", (width, panel * len(panels)), "white")
    draw = ImageDraw.Draw(image)
    x_of = lambda step: margin + (width - 2 * margin) * step / steps.max()  # noqa: E731
    for index, (name, points) in enumerate(panels):
        y0, y1 = index * panel + top, (index + 1) * panel - 18
        if points is None:
            kernel = min(25, len(losses))
            values = np.convolve(losses, np.ones(kernel) / kernel, mode="valid")
            points = list(zip(steps[kernel - 1 :].tolist(), values.tolist()))
        low, high = min(v for _, v in points), max(v for _, v in points)
        y_of = lambda v: y1 - (y1 - y0) * (v - low) / max(high - low, 1e-12)  # noqa: E731
        xy = [(x_of(s), y_of(v)) for s, v in points]
        colour = "black" if index == 0 else "red"
        draw.line(xy, fill=colour, width=2 if index == 0 else 1)
        if index:
            for x, y in xy:
                draw.ellipse([x - 2.5, y - 2.5, x + 2.5, y + 2.5], fill=colour)
        draw.rectangle([margin, y0, width - margin, y1], outline="gray")
        draw.text(
            (margin, y0 - 16),
            f"{name}: {points[0][1]:.4g} at step {points[0][0]} -> {points[-1][1]:.4g} at step "
            f"{points[-1][0]}   (range {low:.4g}-{high:.4g})",
            fill="black",
        )
    draw.text((margin, panel * len(panels) - 14), f"step 0 - {int(steps.max())}", fill="black")
    path.parent.mkdir(parents=True, exist_ok=True)
    image.save(path)


if __name__ == "__main__":
    main()
