"""The learning curve of a training run: a table (JSON lines) and a PNG chart from its metrics.jsonl.

    python experiments/learning_curve.py runs/cpu --out docs/learning_curve_cpu.png

Rows: the training loss averaged over windows of ``--window`` steps, with the held-out style metric
(``val_swd``) of the evaluations in that window. The chart draws the windowed loss (black, left
scale) and ``val_swd`` (red dots, right scale) against the step.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path)
    parser.add_argument("--window", type=int, default=250)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    records = [json.loads(line) for line in (args.run / "metrics.jsonl").read_text().splitlines() if line.strip()]
    train = [(r["step"], r["loss"], r["loss_hist"]) for r in records if "loss" in r]
    evals = [(r["step"], r["val_swd"]) for r in records if "val_swd" in r]
    steps = np.array([s for s, _, _ in train])
    losses = np.array([loss for _, loss, _ in train])
    for start in range(0, int(steps.max()), args.window):
        inside = (steps > start) & (steps <= start + args.window)
        row = {"steps": f"{start + 1}-{start + args.window}", "loss": float(losses[inside].mean()),
               "loss_hist": float(np.mean([h for (s, _, h) in train if start < s <= start + args.window]))}
        row["val_swd"] = [round(v, 4) for s, v in evals if start < s <= start + args.window] or None
        print(json.dumps(row))
    print(json.dumps({"val_swd_start": evals[0][1], "val_swd_end": evals[-1][1], "last_step": int(steps.max()),
                      "seconds": next(r["seconds"] for r in reversed(records) if "seconds" in r),
                      "peak_memory_mb": max(r.get("peak_memory_mb", 0) for r in records)}))
    if args.out:
        chart(args.out, steps, losses, evals, args.window)
        print(f"wrote {args.out}")


def chart(path: Path, steps, losses, evals, window: int, size=(640, 320)) -> None:
    from PIL import Image, ImageDraw

    width, height, margin = size[0], size[1], 40
    image = Image.new("RGB", size, "white")
    draw = ImageDraw.Draw(image)
    kernel = max(1, window // 10)
    smooth = np.convolve(losses, np.ones(kernel) / kernel, mode="valid")
    x_of = lambda step: margin + (width - 2 * margin) * step / steps.max()  # noqa: E731
    low, high = float(smooth.min()), float(smooth.max())
    y_loss = lambda v: height - margin - (height - 2 * margin) * (v - low) / max(high - low, 1e-9)  # noqa: E731
    points = [(x_of(s), y_loss(v)) for s, v in zip(steps[kernel - 1 :], smooth)]
    draw.line(points, fill="black", width=2)
    values = [v for _, v in evals]
    v_low, v_high = min(values), max(values)
    y_val = lambda v: height - margin - (height - 2 * margin) * (v - v_low) / max(v_high - v_low, 1e-9)  # noqa: E731
    for step, value in evals:
        x, y = x_of(step), y_val(value)
        draw.ellipse([x - 3, y - 3, x + 3, y + 3], fill="red")
    draw.rectangle([margin, margin, width - margin, height - margin], outline="gray")
    draw.text((margin, 8), f"loss (black, {low:.3g}-{high:.3g}, mean of {kernel})   val_swd (red, {v_low:.3g}-{v_high:.3g})", fill="black")
    draw.text((margin, height - margin + 8), f"step 0 - {int(steps.max())}", fill="black")
    path.parent.mkdir(parents=True, exist_ok=True)
    image.save(path)


if __name__ == "__main__":
    main()
