"""Which noise fields carry a style's patterns? Training-free fields on the validation split (issue #33).

The noise site (``docs/decisions/2026-12-02-noise-site.md``) can only weigh the fields it is given:
isotropic Gaussian noise at four scales, two fields a scale. Before a training run gives it other
fields, this probe asks the cheap question: given the same colour match, which fields alone come
closer to each validation painting than the benchmark's ``smooth_noise`` baseline (isotropic, 3
voxels)? Each field is three independent channels (RGB) filtered by an axis-aligned Gaussian with
its own standard deviation per grid axis (Z, Y, X; Y is up, so a long Y makes strokes that stand
upright from every orbit view and a short Y with long Z and X makes horizontal layers).

Scored as the benchmark scores (3 metric views, 128^2, 16 spp) on the validation split only
(``VALIDATION_DENSITIES`` x the validation paintings), never the held-out pairs. The table gives the
medians of per-pair ratios to ``smooth_noise`` and, per set of fields, the "oracle" median: each
pair's best field in the set, an upper bound on what a network choosing among those fields per
style could reach with them alone.

    python experiments/noise_field_probe.py --out results/noise_fields
    python experiments/noise_field_probe.py --fields '' --checkpoints runs/x/steps/step_000800.pt   # networks too
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

# Standard deviations in voxels along (Z, Y, X) at 64^3.
FIELDS = {
    "iso1.5": (1.5, 1.5, 1.5),
    "upright": (1.5, 8.0, 1.5),
    "layers": (6.0, 1.5, 6.0),
    "upright_coarse": (3.0, 12.0, 3.0),
    "layers_coarse": (10.0, 3.0, 10.0),
}
# The benchmark's own smooth noise (a zero-padded separable blur) at other standard deviations, in voxels at 64^3.
SMOOTH_NOISE_VOXELS = {"smooth_noise": 3.0, "smooth_noise_6": 6.0, "smooth_noise_9": 9.0, "smooth_noise_12": 12.0}
SETS = {
    "isotropic": ("smooth_noise", "iso1.5", "tuned_noise", "smooth_noise_6", "smooth_noise_9", "smooth_noise_12"),
    "isotropic+oriented": ("smooth_noise", "tuned_noise", *FIELDS),
}


def oriented_noise(shape: tuple, sigmas: tuple, seed: int = 0) -> np.ndarray:
    """RGB noise ``shape + (3,)`` in [0, 1]: white noise per channel filtered by a Gaussian with
    ``sigmas`` voxels along (Z, Y, X) at 64 (scaled with the longest side) in the frequency domain,
    each channel stretched to span [0, 1] as ``benchmark.methods.smooth_noise`` does."""
    import torch

    scale = max(shape) / 64.0
    generator = torch.Generator().manual_seed(seed)
    white = torch.randn((3,) + tuple(shape), generator=generator, dtype=torch.float64)
    spectrum = torch.fft.rfftn(white, dim=(1, 2, 3))
    frequencies = [torch.fft.fftfreq(n, dtype=torch.float64) for n in shape[:2]] + [
        torch.fft.rfftfreq(shape[2], dtype=torch.float64)
    ]
    exponent = sum(
        (sigma * scale) ** 2 * f.view([-1 if axis == a else 1 for a in range(3)]) ** 2
        for axis, (f, sigma) in enumerate(zip(frequencies, sigmas, strict=True))
    )
    field = torch.fft.irfftn(spectrum * torch.exp(-2.0 * torch.pi**2 * exponent), s=tuple(shape), dim=(1, 2, 3))
    field = field.permute(1, 2, 3, 0).numpy()
    low, high = field.reshape(-1, 3).min(axis=0), field.reshape(-1, 3).max(axis=0)
    return np.ascontiguousarray((field - low) / np.maximum(high - low, 1e-12), dtype=np.float32)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=Path("results/noise_fields"))
    parser.add_argument("--paintings", type=int, default=0, help="only the first N validation paintings (0: all)")
    parser.add_argument(
        "--checkpoints",
        nargs="*",
        type=Path,
        default=[],
        help="networks to score too (feed-forward with the colour match, as the benchmark's network row)",
    )
    parser.add_argument(
        "--fields",
        default=None,
        help="comma-separated names of the fields to score (default: all; '' for none but smooth_noise, which "
        "every ratio needs); rows already in <out>/rows.jsonl for other fields and networks are kept",
    )
    args = parser.parse_args(argv)

    from mistyle.benchmark.methods import smooth_noise, tuned_noise
    from mistyle.benchmark.runner import metric_views, score
    from mistyle.data.heldout import VALIDATION_DENSITIES, held_out_density
    from mistyle.files import load_style
    from mistyle.pipeline import Pipeline, PipelineSettings
    from mistyle.train.dataset import validation_paintings
    from mistyle.train.recipes import VALIDATION_RES, VALIDATION_SPP

    pipeline = Pipeline(PipelineSettings(refine_steps=0, refine_path_steps=0))
    views = metric_views(pipeline.camera_distance)
    options = dict(
        res=VALIDATION_RES, spp=VALIDATION_SPP, density_scale=pipeline.density_scale, radiance=pipeline.radiance
    )
    paintings = validation_paintings()[: args.paintings or None]
    networks = {
        checkpoint_label(path): Pipeline(PipelineSettings(checkpoint=path, refine_steps=0, refine_path_steps=0))
        for path in args.checkpoints
    }
    args.out.mkdir(parents=True, exist_ok=True)
    rows_file = args.out / "rows.jsonl"
    old = [json.loads(line) for line in rows_file.read_text().splitlines()] if rows_file.exists() else []
    rows = []
    for spec in VALIDATION_DENSITIES:
        density = held_out_density(spec, Path("data") / "heldout")
        every = [*SMOOTH_NOISE_VOXELS, "tuned_noise", *FIELDS]
        wanted = every if args.fields is None else [name for name in args.fields.split(",") if name]
        fields = {"smooth_noise": smooth_noise(density.shape)}  # every ratio's reference
        for name in wanted:
            if name == "tuned_noise":  # the benchmark's own
                fields[name] = tuned_noise(density.shape)
            elif name in SMOOTH_NOISE_VOXELS:
                fields[name] = smooth_noise(density.shape, sigma=SMOOTH_NOISE_VOXELS[name] / 64)
            else:
                fields[name] = oriented_noise(density.shape, FIELDS[name])
        for path in paintings:
            style = load_style(path)
            makers = {
                name: lambda field=field: pipeline.stylizer.match_colours([field], [density], style)[0]
                for name, field in fields.items()
            }
            for label, network in networks.items():
                makers[label] = lambda network=network: network.stylize(density, style).albedos[0]
            for name, make in makers.items():
                start = time.perf_counter()
                albedo = make()
                metrics = score(density, albedo, style, views, **options)[0]
                rows.append(dict(field=name, density=spec.name, style=path.stem, **metrics))
                print(
                    f"{spec.name} {path.stem} {name}: RGB {metrics['rgb_swd']:.4f} patch {metrics['patch_swd']:.4f} "
                    f"({time.perf_counter() - start:.1f} s)",
                    flush=True,
                )
    fresh = {(row["field"], row["density"], row["style"]) for row in rows}
    rows = [row for row in old if (row["field"], row["density"], row["style"]) not in fresh] + rows
    rows_file.write_text("".join(json.dumps(row) + "\n" for row in rows))
    write_table(args.out, rows)


def checkpoint_label(path: Path) -> str:
    """``network:<run>/<step>`` for a run's kept checkpoint, ``network:<file name>`` otherwise."""
    return f"network:{path.parent.parent.name}/{path.stem}" if path.parent.name == "steps" else f"network:{path.stem}"


def write_table(out: Path, rows: list[dict]) -> None:
    pairs = sorted({(row["density"], row["style"]) for row in rows})
    table = {(row["field"], row["density"], row["style"]): row for row in rows}
    names = [name for name in dict.fromkeys(row["field"] for row in rows) if all((name, *p) in table for p in pairs)]
    fields = [name for name in names if not name.startswith("network:")]

    def ratios(name, key, against="smooth_noise"):
        return np.array([table[(name, *pair)][key] / table[(against, *pair)][key] for pair in pairs])

    def against(name, baseline):
        if baseline not in names:
            return "n/a | n/a"
        return " | ".join(f"{np.median(ratios(name, key, baseline)):.3f}" for key in ("rgb_swd", "patch_swd"))

    lines = [
        f"Training-free fields and networks (feed-forward), each + the colour match, on the validation split "
        f"({len(pairs)} pairs): medians of per-pair ratios (lower is better) to `smooth_noise` and to "
        '`tuned_noise`; "score": the mean of the two medians against `smooth_noise` (what a recipe\'s '
        '`select="validation:noise"` minimises); "best field for": pairs where the field has the lowest patch '
        "SWD of the training-free fields. `python experiments/noise_field_probe.py`.",
        "",
        "| field or network | RGB x noise | patch x noise | score | RGB x tuned | patch x tuned | best field for |",
        "|---|---|---|---|---|---|---|",
    ]
    patch = np.stack([ratios(name, "patch_swd") for name in fields])
    best = np.argmin(patch, axis=0)
    for name in names:
        rgb, patch_ratio = (np.median(ratios(name, key)) for key in ("rgb_swd", "patch_swd"))
        wins = int((best == fields.index(name)).sum()) if name in fields else "-"
        lines.append(
            f"| {name} | {rgb:.3f} | {patch_ratio:.3f} | {(rgb + patch_ratio) / 2:.3f} | "
            f"{against(name, 'tuned_noise')} | {wins} |"
        )
    lines += ["", "| set (per pair its best field) | RGB x noise | patch x noise |", "|---|---|---|"]
    for set_name, members in SETS.items():
        members = [m for m in members if m in fields]
        chosen = np.argmin(np.stack([ratios(m, "patch_swd") for m in members]), axis=0)
        rgb = np.stack([ratios(m, "rgb_swd") for m in members])[chosen, np.arange(len(pairs))]
        best_patch = np.stack([ratios(m, "patch_swd") for m in members])[chosen, np.arange(len(pairs))]
        lines.append(f"| {set_name} ({', '.join(members)}) | {np.median(rgb):.3f} | {np.median(best_patch):.3f} |")
    (out / "table.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
