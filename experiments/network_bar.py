"""Every network scored on the held-out split, checked against issue #33's bar (no new renders).

Issue #33 is done when the feed-forward network (``--refine 0``, colour match included, no look) has,
on the held-out split's medians: RGB and patch SWD at most 0.9x those of ``smooth_noise`` + colour
match; a structure distance below that baseline's on at least 75% of pairs; lower RGB and patch SWD
than the ``uniform`` baseline on every pair. This reads the held-out rows every network and field was
scored with (the same 28 pairs, renders and metrics; ``mistyle-bench`` and the experiments that
wrote them) and checks each against the bar, with ``smooth_noise`` and ``uniform`` from
``results/benchmark/rows.jsonl``. It also lists the pairs where a method does not beat ``uniform``.

    python experiments/network_bar.py          # results/network_bar/table.md
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
BASELINES = REPO / "results/benchmark/rows.jsonl"
SOURCES = (
    # (rows file, method in it, label, what it is)
    ("results/benchmark/rows.jsonl", "network", "skpn_noise (shipped)", "the noise site on skpn_cpu, step 800"),
    ("results/noise_site/benchmark/rows.jsonl", "network_skpn_cpu", "skpn_cpu", "the recipe before the noise site"),
    (
        "results/noise_site/benchmark/rows.jsonl",
        "network_noise_stage2",
        "noise stage 2",
        "300 more steps at patch weight 0.5",
    ),
    ("results/validation_split/heldout/rows.jsonl", "network_rgb3_600", "rgb3", "three noise fields a scale"),
    ("results/validation_split/heldout/rows.jsonl", "network_oriented_600", "oriented", "oriented noise fields"),
    ("results/benchmark/rows.jsonl", "tuned_noise", "tuned_noise (no network)", "training-free"),
    ("results/benchmark/rows.jsonl", "density_ramp", "density_ramp (no network)", "training-free"),
    ("results/benchmark/rows.jsonl", "look", "look (a fit, not feed-forward)", "the default output's albedo"),
)
BAR = {"rgb": 0.9, "patch": 0.9, "structure_share": 0.75}


def rows_of(path: Path, method: str) -> dict:
    rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return {(r["density"], r["style"]): r for r in rows if r["method"] == method}


def check(rows: dict, noise: dict, uniform: dict) -> dict:
    """The bar's quantities for one method's rows (pairs it shares with both baselines)."""
    pairs = sorted(set(rows) & set(noise) & set(uniform))
    ratio = {key: [rows[p][key] / noise[p][key] for p in pairs] for key in ("rgb_swd", "patch_swd")}
    structure = [p for p in pairs if rows[p].get("structure") is not None and noise[p].get("structure") is not None]
    closer = sum(rows[p]["structure"] < noise[p]["structure"] for p in structure)
    losing = [
        p
        for p in pairs
        if not (rows[p]["rgb_swd"] < uniform[p]["rgb_swd"] and rows[p]["patch_swd"] < uniform[p]["patch_swd"])
    ]
    result = {
        "pairs": len(pairs),
        "rgb": float(np.median(ratio["rgb_swd"])),
        "patch": float(np.median(ratio["patch_swd"])),
        "closer": closer,
        "structure_pairs": len(structure),
        "losing": losing,
    }
    result["meets"] = {
        "rgb": result["rgb"] <= BAR["rgb"],
        "patch": result["patch"] <= BAR["patch"],
        "structure": bool(structure) and closer >= BAR["structure_share"] * len(structure),
        "uniform": not losing,
    }
    return result


def table(results: list[tuple]) -> str:
    mark = {True: "yes", False: "**no**"}
    lines = [
        "Issue #33's bar on the held-out split (28 pairs: smoke64 and pyroclastic64 x 14 held-out pictures; "
        "128^2 renders, 16 spp, 3 views), each method with the product's colour match. Medians of per-pair ratios "
        "to `smooth_noise` + colour match; structure: pairs whose structure distance is below `smooth_noise`'s; "
        "uniform: pairs with both SWDs below the `uniform` baseline's. `python experiments/network_bar.py`.",
        "",
        "| method | what | RGB x noise (<= 0.9) | patch x noise (<= 0.9) | structure closer (>= 75%) "
        "| beats uniform (all) | meets the bar |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, what, r in results:
        m = r["meets"]
        lines.append(
            f"| {label} | {what} | {r['rgb']:.3f} {mark[m['rgb']]} | {r['patch']:.3f} {mark[m['patch']]} | "
            f"{r['closer']}/{r['structure_pairs']} {mark[m['structure']]} | "
            f"{r['pairs'] - len(r['losing'])}/{r['pairs']} {mark[m['uniform']]} | {mark[all(m.values())]} |"
        )
    lines += ["", "Pairs where a method does not beat `uniform` on both SWDs:", ""]
    for label, _, r in results:
        names = ", ".join(f"{d}:{s}" for d, s in r["losing"]) or "none"
        lines.append(f"- {label}: {names}")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="results/network_bar")
    args = parser.parse_args()
    noise, uniform = rows_of(BASELINES, "smooth_noise"), rows_of(BASELINES, "uniform")
    results = [
        (label, what, check(rows_of(REPO / path, method), noise, uniform)) for path, method, label, what in SOURCES
    ]
    out = REPO / args.out
    out.mkdir(parents=True, exist_ok=True)
    (out / "table.md").write_text(table(results))
    print(table(results))


if __name__ == "__main__":
    main()
