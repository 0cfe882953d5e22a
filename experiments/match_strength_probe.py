"""The colour match's strength on held-out pairs where no matched field beats ``uniform`` (#33, a diagnostic).

On ``pyroclastic64`` x ``texture_mossy_rock`` every method that goes through the colour match, the
network, the training-free fields and a look, renders further from the picture than one colour
matched to it (``results/network_bar/table.md``). The explanation offered: the dense cloud's shading
already spreads the rendered colours, and a map of colour alone cannot take that spread back, so
matching the voxels to the picture's whole spread overshoots. If so, moving the voxels less of the
way should bring the matched fields closer on that pair, and at some point below ``uniform``'s
distance. Two ways of moving less are scored, with the benchmark's scoring, beside ``uniform``:

* ``strength`` below 1 (what ``--strength`` does): each voxel moves that fraction of the way from the
  field's own colour to its matched colour;
* ``spread``: the fully matched albedo blended towards the ``uniform`` baseline's one colour, keeping
  that fraction of its deviation from it (the spread shrinks about the matched colour).

    python experiments/match_strength_probe.py        # results/match_strength/ (about 3 minutes)
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

STRENGTHS = (0.0, 0.25, 0.5, 0.75, 1.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--pairs", default="pyroclastic64:texture_mossy_rock,pyroclastic64:texture_rusty_metal")
    parser.add_argument("--out", default="results/match_strength")
    args = parser.parse_args()

    from mistyle.benchmark.methods import METHODS, Context, smooth_noise
    from mistyle.benchmark.runner import metric_views, score
    from mistyle.benchmark.splits import split_pairs, split_styles
    from mistyle.data.heldout import held_out_density
    from mistyle.files import load_style
    from mistyle.stylizer import Stylizer

    stylizer = Stylizer(None)
    context = Context(stylizer, metric_views(stylizer.config.render.camera_distance))
    styles = split_styles("heldout")
    wanted = [tuple(pair.split(":")) for pair in args.pairs.split(",")]
    specs = {spec.name: spec for spec, _ in split_pairs("heldout")}
    rows = []
    for density_name, style_name in wanted:
        density = held_out_density(specs[density_name])
        style = load_style(styles[style_name]["path"])
        fields = {
            "network": METHODS["network_unmatched"].albedo(context, density, style),
            "smooth_noise": smooth_noise(density.shape, context.seed),
        }
        colour = METHODS["uniform"].albedo(context, density, style)
        arms = [("uniform", None, colour)]
        for name, field in fields.items():
            matched = {
                strength: stylizer.match_colours([field], [density], style, strength=strength)[0]
                for strength in STRENGTHS
            }
            arms += [(name, f"strength {strength:.2f}", albedo) for strength, albedo in matched.items()]
            full = matched[1.0]
            arms += [(name, f"spread {kept:.2f}", colour + kept * (full - colour)) for kept in STRENGTHS[1:-1]]
        for name, moved, albedo in arms:
            metrics, _ = score(
                density,
                albedo,
                style,
                context.views,
                res=128,
                spp=16,
                density_scale=context.density_scale,
                radiance=context.radiance,
            )
            row = {"density": density_name, "style": style_name, "field": name, "moved": moved}
            row.update({key: float(metrics[key]) for key in ("rgb_swd", "patch_swd", "structure")})
            rows.append(row)
            print(json.dumps(row), flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    (out / "table.md").write_text(table(rows))
    print(table(rows))


def table(rows: list[dict]) -> str:
    lines = [
        "Matched fields at several colour-match strengths against `uniform` on the pairs where no matched method "
        "beats it (128^2, 16 spp, the benchmark's views and metrics). `python experiments/match_strength_probe.py`.",
        "",
        "| pair | field | moved | RGB SWD | patch SWD | structure | both SWDs below uniform's |",
        "|---|---|---|---|---|---|---|",
    ]
    uniform = {(r["density"], r["style"]): r for r in rows if r["field"] == "uniform"}
    for r in rows:
        base = uniform[(r["density"], r["style"])]
        below = r["field"] != "uniform" and r["rgb_swd"] < base["rgb_swd"] and r["patch_swd"] < base["patch_swd"]
        moved = r["moved"] or ""
        lines.append(
            f"| {r['density']}:{r['style']} | {r['field']} | {moved} | {r['rgb_swd']:.4f} | {r['patch_swd']:.4f} | "
            f"{r['structure']:.3f} | {'yes' if below else ''} |"
        )
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
