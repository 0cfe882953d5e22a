"""Does a gradient term in the look's objective give a dense cloud the style's strokes? (#48 part 4)

On the held-out split the default output's structure is closer to the style than tuned noise + colour
match on 13 of 14 thin-smoke pairs but 2-3 of 14 dense-cloud pairs, where the render shows a few
smooth blobs of the style's colours: its orientations at coarse scales and its fine gradients differ
from the style's (``experiments/structure_levels.py``). The look's objective compares colours (RGB) and
raw 5x5 patches (weight 0.05); nothing in it asks for the style's gradients, whose orientations and
sizes are what strokes are. The arms add ``SlicedObjective``'s structure term: the sliced Wasserstein
distance between the views' and the style's gradients (luminance and two opponent channels, at 1, 2
and 4 times the views' pixel, the style taken at the scale a final render shows it), each scale
divided by the style's RMS gradient:

* ``look_gradient03`` / ``look_gradient3``: the default look with the term weighted 0.03 or 0.3 (the
  default's RGB, patch and smoothness terms end near 0.01 together, the gradient term near 1.4: the
  first gives it about four times the rest, the second lets it lead). Chosen from a probe on three
  dense validation pairs (``probe/``: weights 0.003 to 1, and the solid texture's fine band added to
  the fitted look), where 0.03 and 0.3 moved structure most and the band did not.

Pairs: the validation split's two 64^3 densities (a thin smoke and a dense cloud) with all 14
validation styles, 28 pairs, so that a median moves by about half the look seed's spread over six
pairs (``results/structure_seed_spread/``: 0.028); scoring as users see it (256^2, 64 spp, OIDN), with
the default and tuned noise + colour match in the same run.

Rule written before the rows: among the arms whose median RGB and patch SWD are each at most 1.05x the
default's and whose median fit time is at most 1.5x, the arm with the most pairs whose structure is
closer than tuned noise's replaces the default if it has at least 3 more such pairs than the default
(of 28) and at least 2 more on the dense cloud (of 14); ties go to the smaller weight.

    .venv/bin/python experiments/look_structure_study.py              # about 30 min on 2 cores
    .venv/bin/python experiments/look_structure_study.py --heldout look_gradient03
    .venv/bin/python experiments/look_structure_study.py --report-only
    .venv/bin/python experiments/look_structure_study.py --compare heldout   # also heldout128, real
    .venv/bin/python experiments/look_structure_study.py --sheet             # about 5 min

``--sheet``: ``SHEET_PAIRS`` of the held-out split scored again in one run (the new default, the default
before it, tuned noise, the solid texture) and ``heldout_sheet.jpg`` of their first views at 256 px.
``--compare SPLIT``: once the chosen arm is the default and its rows have replaced the default's in the
README's folder of that split, the new default against the old one (``before/``), the look of #48's
filing and tuned noise, into ``SPLIT_comparison.json``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "experiments"))

OUT = ROOT / "results" / "look_structure_study"
ARMS = {"look_gradient03": 0.03, "look_gradient3": 0.3}


def register_arms() -> list[str]:
    """The arms as benchmark methods (a study's hook into the registry; the product's methods are unchanged)."""
    from mistyle.benchmark.methods import METHODS, Method
    from mistyle.look import LookSettings

    def arm(weight):
        def albedo(context, density, style):
            pipeline = context.pipeline(refine_steps=0, refine_path_steps=0)
            look = pipeline.fit_look(density, style, look_settings=LookSettings(structure_weight=weight))
            return look.stylize(density)

        return albedo

    for name, weight in ARMS.items():
        description = f"the default look with the objective's gradient term weighted {weight}"
        METHODS[name] = Method(name, "ablation", description, arm(weight), True)
    # Registered for reports (structure_levels.py --arms), not run by the study: the default before it.
    METHODS["look_before"] = Method("look_before", "ablation", "the look without the gradient term", arm(0.0), True)
    return list(ARMS)


def pairs() -> list:
    from mistyle.benchmark.splits import split_pairs

    return split_pairs("validation", ["val_smoke64", "val_pyroclastic64"])


def rows_of(path: Path) -> dict:
    import json

    rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return {(row["method"], row["density"], row["style"]): row for row in rows}


def compare(now: Path, before: Path, out: Path) -> dict:
    """The new default (``now``'s ``default`` rows) against the default before it (``before``'s), the look
    of #48's filing (``look_zeros``, where ``now`` has it) and tuned noise + colour match, per density
    and over all pairs; written to ``out``."""
    import json

    import numpy as np

    ours, old = rows_of(now), rows_of(before)
    pairs = sorted((d, s) for m, d, s in ours if m == "default" and ("default", d, s) in old)
    record = {}
    for name in sorted({d for d, _ in pairs}) + ["all"]:
        chosen = [(d, s) for d, s in pairs if name in ("all", d)]

        def values(rows, method, key, chosen=chosen):
            return np.array([rows[(method, d, s)][key] or np.nan for d, s in chosen], dtype=float)

        entry = {"pairs": len(chosen)}
        tuned = values(ours, "tuned_noise", "structure")
        for label, rows, method in (("now", ours, "default"), ("before", old, "default")):
            entry[f"{label}_structure_closer_than_tuned_noise"] = int(np.sum(values(rows, method, "structure") < tuned))
            for key in ("rgb_swd", "patch_swd", "structure", "hue_coverage"):
                entry[f"{label}_median_{key}"] = float(np.nanmedian(values(rows, method, key)))
        entry["now_structure_closer_than_before"] = int(
            np.sum(values(ours, "default", "structure") < values(old, "default", "structure"))
        )
        if all(("look_zeros", d, s) in ours for d, s in chosen):
            zeros = {key: values(ours, "look_zeros", key) for key in ("rgb_swd", "patch_swd", "structure")}
            entry["now_structure_closer_than_look_zeros"] = int(
                np.sum(values(ours, "default", "structure") < zeros["structure"])
            )
            for key in ("rgb_swd", "patch_swd"):
                entry[f"now_median_{key}_over_look_zeros"] = entry[f"now_median_{key}"] / float(np.median(zeros[key]))
        record[name] = entry
    out.write_text(json.dumps(record, indent=1) + "\n")
    return record


SHEET_PAIRS = (
    ("pyroclastic64", "hokusai_great_wave"),
    ("pyroclastic64", "van_gogh_starry_night"),
    ("pyroclastic64", "photo_nasa_carina_pillar"),
    ("pyroclastic64", "texture_rusty_metal"),
    ("smoke64", "signac_la_calanque"),
    ("smoke64", "munch_the_scream"),
)
SHEET_METHODS = ("default", "look_before", "tuned_noise", "solid_texture")


def heldout_sheet() -> Path:
    """Held-out pairs (``SHEET_PAIRS``) scored again in one run, the new default next to the default before
    it (``look_before``) and the baselines, into ``OUT/heldout_sheet/``; then ``heldout_sheet.jpg``: per
    pair the style and each method's first view at 256 px, large enough to see strokes."""
    from study import USER_SCORING

    from mistyle.benchmark.runner import ROWS_FILE, SAVED_TILE, read_rows, run, write_sheet
    from mistyle.benchmark.splits import split_pairs

    register_arms()
    folder = OUT / "heldout_sheet"
    chosen = [pair for pair in split_pairs("heldout") if (pair[0].name, pair[1]) in SHEET_PAIRS]
    run(folder, chosen, list(SHEET_METHODS), split="heldout", resume=True, **USER_SCORING)
    path = OUT / "heldout_sheet.jpg"
    write_sheet(read_rows(folder / ROWS_FILE), folder / "tiles", path, side=SAVED_TILE)
    return path


COMPARISONS = {
    "heldout": ROOT / "results" / "solid_texture_study" / "heldout" / "rows.jsonl",
    "heldout128": ROOT / "results" / "benchmark-heldout128" / "rows.jsonl",
    "real": ROOT / "results" / "benchmark-real" / "rows.jsonl",
}


def main(argv=None) -> None:
    import argparse

    from study import arm_study

    if argv is None:
        argv = sys.argv[1:]
    if argv[:1] == ["--sheet"]:
        print(f"wrote {heldout_sheet()}")
        return
    if argv[:1] == ["--compare"]:  # the new default's rows in the README's folders against the old default's
        parser = argparse.ArgumentParser(description="compare the default's rows with those before it")
        parser.add_argument("--compare", required=True, choices=list(COMPARISONS))
        split = parser.parse_args(argv).compare
        before = OUT / "before" / f"{split}_rows.jsonl"
        print(json.dumps(compare(COMPARISONS[split], before, OUT / f"{split}_comparison.json"), indent=1))
        return
    arm_study(__doc__.splitlines()[0], OUT, register_arms, pairs, argv, baselines=("tuned_noise",))


if __name__ == "__main__":
    main()
