"""Does a validation split choose as the held-out split would? Networks scored on both, compared (issue #33).

Choosing checkpoints and arms on a split says something only if that split ranks networks as the
held-out split does. This scores networks on the benchmark's ``validation`` split (the validation
styles: other paintings, photographs and textures, on a smoke and a pyroclastic cloud of other
seeds) with the benchmark's own runner, next to the training-free baselines, and compares the
networks' standing there with their held-out rows (``--heldout``, scored before) and, for contrast,
with the old validation split (13 training-collection paintings on one smoke density: the noise
probe's rows, ``--old``).

Per split and network: the medians of per-pair ratios to ``smooth_noise`` (RGB and patch SWD) and
the structure median; per arm against the first network (the shipped one): the geometric mean of
its per-pair ratios and the pairs it wins. A split agrees with the held-out one when it orders the
networks the same way and makes the same call on every arm ("better" or "worse" than the shipped
network, by the geometric mean).

    python experiments/split_agreement.py --network skpn_noise=mistyle/checkpoints/skpn_noise.pt \\
        --network rgb3_600=runs/rgb3/steps/step_000600.pt --heldout results/noise_rgb/benchmark \\
        --old results/noise_fields/rows.jsonl --out results/validation_split

Network labels are ``<run>_<step>`` (``rgb3_600`` is ``runs/rgb3/steps/step_000600.pt``), as the
held-out rows name them (``network_rgb3_600``) and the probe's (``network:rgb3/step_000600``).
Writes ``<out>/validation/`` (the benchmark's rows, table and contact sheet, networks and baselines),
with ``--score-heldout`` ``<out>/heldout/`` (the networks scored on the held-out split, for checkpoints
retrained since ``--heldout`` was scored), and ``<out>/table.md``.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np

BASELINES = ("smooth_noise", "tuned_noise")  # what the ratios need; uniform fits take minutes a pair
METRICS = (("rgb_swd", "RGB SWD"), ("patch_swd", "patch SWD"), ("structure", "structure"))


def probe_label(field: str) -> str | None:
    """``network:rgb3/step_000600`` -> ``rgb3_600``; ``network:skpn_noise`` -> ``skpn_noise``."""
    if not field.startswith("network:"):
        return None
    name = field.removeprefix("network:")
    if "/" not in name:
        return name
    run, step = name.split("/")
    return f"{run}_{int(step.removeprefix('step_'))}"


def load_split(path: Path) -> dict:
    """``{(method, density, style): metrics}`` from a benchmark folder's ``rows.jsonl`` (methods
    ``network_<label>``) or a noise probe's ``rows.jsonl`` (fields ``network:<run>/<step>``); networks
    are keyed by their label, baselines by their name."""
    rows = [json.loads(line) for line in (path / "rows.jsonl" if path.is_dir() else path).read_text().splitlines()]
    out = {}
    for row in rows:
        if "field" in row:
            method = probe_label(row["field"]) or row["field"]
        else:
            method = row["method"].removeprefix("network_") if row["method"].startswith("network_") else row["method"]
        out[method, row["density"], row["style"]] = {key: row.get(key) for key, _ in METRICS}
    return out


def standing(rows: dict, networks: list[str]) -> dict:
    """Per network: medians of per-pair ratios to ``smooth_noise``, the structure median, and against
    the first network the geometric mean of per-pair ratios and the pairs won, per metric."""
    pairs = sorted({(d, s) for m, d, s in rows if m == "smooth_noise"})
    shipped = networks[0]
    result = {}
    for label in networks:
        mine = [(pair, rows.get((label, *pair))) for pair in pairs]
        mine = [(pair, metrics) for pair, metrics in mine if metrics is not None]
        if not mine:
            continue
        entry = {"pairs": len(mine)}
        for key, _ in METRICS[:2]:
            entry[f"{key}_x_noise"] = float(
                np.median([m[key] / rows[("smooth_noise", *pair)][key] for pair, m in mine])
            )
        entry["structure"] = float(np.median([m["structure"] for _, m in mine if m["structure"] is not None]))
        for key, _ in METRICS:
            ratios = [
                m[key] / rows[(shipped, *pair)][key]
                for pair, m in mine
                if (shipped, *pair) in rows and m[key] is not None and rows[(shipped, *pair)][key] is not None
            ]
            entry[f"{key}_x_shipped"] = float(np.exp(np.mean(np.log(ratios)))) if ratios else float("nan")
            entry[f"{key}_wins"] = int(sum(r < 1 for r in ratios))
        result[label] = entry
    return result


def kendall_tau(a: list[float], b: list[float]) -> float:
    """Kendall's tau between two orderings of the same items (ties count as neither)."""
    concordant = discordant = 0
    for i in range(len(a)):
        for j in range(i + 1, len(a)):
            sign = np.sign(a[i] - a[j]) * np.sign(b[i] - b[j])
            concordant += sign > 0
            discordant += sign < 0
    pairs = len(a) * (len(a) - 1) / 2
    return float((concordant - discordant) / pairs) if pairs else float("nan")


def write_table(out: Path, split_rows: dict[str, dict], networks: list[str]) -> str:
    """``<out>/table.md`` from each split's rows (``load_split``): the networks' standing, the agreement
    with the held-out split, and each arm's calls density by density."""
    splits = {split: standing(rows, networks) for split, rows in split_rows.items()}
    lines = [
        "Networks on each split (feed-forward, colour match included). Medians of per-pair ratios to "
        "`smooth_noise` (lower is better), the structure median, and against the first network the "
        "geometric mean of per-pair ratios with the pairs won.",
        "",
        "| split | network | pairs | RGB x noise | patch x noise | structure | RGB x shipped (won) | "
        "patch x shipped (won) | structure x shipped (won) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for split, table in splits.items():
        for label in networks:
            if label not in table:
                continue
            e = table[label]
            lines.append(
                f"| {split} | {label} | {e['pairs']} | {e['rgb_swd_x_noise']:.3f} | {e['patch_swd_x_noise']:.3f} | "
                f"{e['structure']:.3f} | "
                + " | ".join(f"{e[f'{key}_x_shipped']:.3f} ({e[f'{key}_wins']}/{e['pairs']})" for key, _ in METRICS)
                + " |"
            )
    reference = splits.get("held-out")
    if reference:
        lines += [
            "",
            "Agreement with the held-out split: Kendall's tau of the networks' order by each median (1: the "
            "same order), and the calls on each arm against the shipped network (better when the geometric "
            "mean of per-pair ratios is below 1) that match the held-out split's.",
            "",
            "| split | networks | tau RGB x noise | tau patch x noise | tau structure | calls matching held-out |",
            "|---|---|---|---|---|---|",
        ]
        for split, table in splits.items():
            if split == "held-out":
                continue
            common = [label for label in networks if label in table and label in reference]
            taus = [
                kendall_tau([reference[n][key] for n in common], [table[n][key] for n in common])
                for key in ("rgb_swd_x_noise", "patch_swd_x_noise", "structure")
            ]
            calls = [
                (table[n][f"{key}_x_shipped"] < 1) == (reference[n][f"{key}_x_shipped"] < 1)
                for n in common[1:]
                for key, _ in METRICS
            ]
            taus_text = " | ".join(f"{t:+.2f}" for t in taus)
            lines.append(f"| {split} | {len(common)} | {taus_text} | {sum(calls)}/{len(calls)} |")
    lines += [
        "",
        "Per density: each arm against the shipped network on that density's pairs alone (geometric mean of "
        "per-pair ratios; below 1 the arm is better). Splits of one density of a kind make these calls once.",
        "",
        "| split | density | network | pairs | RGB x shipped | patch x shipped | structure x shipped |",
        "|---|---|---|---|---|---|---|",
    ]
    for split, rows in split_rows.items():
        for density in sorted({d for _, d, _ in rows}):
            mine = {key: value for key, value in rows.items() if key[1] == density}
            table = standing(mine, networks)
            for label in networks[1:]:
                if label in table:
                    e = table[label]
                    lines.append(
                        f"| {split} | {density} | {label} | {e['pairs']} | "
                        + " | ".join(f"{e[f'{key}_x_shipped']:.3f}" for key, _ in METRICS)
                        + " |"
                    )
    text = "\n".join(lines) + "\n"
    (out / "table.md").write_text(text)
    return text


def score_split(folder: Path, split: str, networks: dict[str, Path], cache: Path, baselines_from: Path | None = None):
    """``split``'s rows in ``folder``: the baselines (copied from ``baselines_from``'s rows when given,
    else scored) and each network as ``network_<label>``, with the benchmark's report. Rows already
    there are kept (rerun a network by deleting its rows)."""
    from mistyle.benchmark.runner import checkpoint_id, read_rows, report, run, tile_path, write_rows
    from mistyle.benchmark.splits import split_pairs

    pairs = split_pairs(split)
    folder.mkdir(parents=True, exist_ok=True)
    if baselines_from is not None and not (folder / "rows.jsonl").exists():
        # The baselines' rows, and those of any network whose very file was scored there.
        same = {f"network_{label}": checkpoint_id(path) for label, path in networks.items()}
        copied = [
            row
            for row in read_rows(baselines_from / "rows.jsonl")
            if row.method in BASELINES or same.get(row.method) == row.checkpoint
        ]
        write_rows(folder / "rows.jsonl", copied)
        for row in copied:
            if tile_path(baselines_from / "tiles", row).exists():
                (folder / "tiles").mkdir(exist_ok=True)
                shutil.copyfile(tile_path(baselines_from / "tiles", row), tile_path(folder / "tiles", row))
    run(folder, pairs, list(BASELINES), cache=cache, split=split, resume=True)
    for label, checkpoint in networks.items():
        method = f"network_{label}"
        if sum(row.method == method for row in read_rows(folder / "rows.jsonl")) == len(pairs):
            continue
        scratch = folder / "scratch" / label
        done = [row for row in read_rows(folder / "rows.jsonl") if row.method == method]
        for row in done:
            row.method = "network"
        scratch.mkdir(parents=True, exist_ok=True)
        started = read_rows(scratch / "rows.jsonl")  # an interrupted run's rows
        keys = {row.key() for row in started}
        same = [row for row in done if row.checkpoint == checkpoint_id(checkpoint) and row.key() not in keys]
        write_rows(scratch / "rows.jsonl", started + same)
        rows = run(scratch, pairs, ["network"], checkpoint=checkpoint, cache=cache, split=split, resume=True)
        kept = [row for row in read_rows(folder / "rows.jsonl") if row.method != method]
        for row in rows:
            source = tile_path(scratch / "tiles", row)
            row.method = method
            if source.exists():
                shutil.copyfile(source, tile_path(folder / "tiles", row))
        write_rows(folder / "rows.jsonl", kept + rows)
        shutil.rmtree(scratch)
    shutil.rmtree(folder / "scratch", ignore_errors=True)
    report(folder)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--network", action="append", default=[], metavar="LABEL=CHECKPOINT", help="the shipped network first"
    )
    parser.add_argument(
        "--heldout", type=Path, required=True, help="benchmark folder with held-out rows (the baselines' at least)"
    )
    parser.add_argument(
        "--score-heldout",
        action="store_true",
        help="score the networks on the held-out split too, in <out>/heldout (baselines copied from --heldout)",
    )
    parser.add_argument("--old", type=Path, default=None, help="the noise probe's rows on the old validation split")
    parser.add_argument("--out", type=Path, default=Path("results/validation_split"))
    parser.add_argument("--cache", type=Path, default=Path("data") / "heldout")
    args = parser.parse_args(argv)
    networks = {}
    for text in args.network:
        label, _, path = text.partition("=")
        if not label or not path or not Path(path).is_file():
            raise SystemExit(f"--network takes LABEL=CHECKPOINT with an existing file, got {text!r}")
        networks[label] = Path(path)
    args.out.mkdir(parents=True, exist_ok=True)
    score_split(args.out / "validation", "validation", networks, args.cache)
    heldout = args.heldout
    if args.score_heldout:
        heldout = args.out / "heldout"
        score_split(heldout, "heldout", networks, args.cache, baselines_from=args.heldout)
    split_rows = {"held-out": load_split(heldout)}
    if args.old is not None:
        split_rows["old validation"] = load_split(args.old)
    split_rows["validation"] = load_split(args.out / "validation")
    print(write_table(args.out, split_rows, list(networks)), end="")


if __name__ == "__main__":
    main()
