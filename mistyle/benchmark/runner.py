"""The benchmark's one runner: pairs x methods -> albedos -> path-traced metric views -> rows, table, sheet.

Rows live in ``<out>/rows.jsonl``, one ``Row`` a line. A row is identified by its method, pair and
settings (``Row.key``): running again replaces the rows it recomputes and keeps every other, and
``resume`` skips the ones already there. ``report`` rewrites ``<out>/table.md`` (medians per method,
and medians of per-pair ratios to the uniform baseline on the same pairs and settings),
``<out>/sheet.jpg`` (per pair: the style, then each method's first metric view) and
``<out>/index.html``. Rows of several settings (or splits) in one file each get their own table,
under a line saying so: medians and ratios never mix them.

``mistyle-bench`` holds its folder as mistyle's (``owned_folder``, ``mistyle.ownership``): one run writes
it at a time, a folder holding a file the benchmark did not write is refused, and the files written
are recorded in its manifest. A damaged ``rows.jsonl`` is refused with its line number, never read
in part.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import re
import subprocess
from dataclasses import MISSING, asdict, dataclass, fields
from pathlib import Path

import numpy as np

METRIC_VIEWS = 3
"""Metric views, evenly around the orbit from the held-out view."""
ROWS_FILE, TABLE_FILE, SHEET_FILE, INDEX_FILE = "rows.jsonl", "table.md", "sheet.jpg", "index.html"
REPORT_FILES = (TABLE_FILE, SHEET_FILE, INDEX_FILE)
TILE = 128
"""The side of a pair's cell on ``sheet.jpg`` (committed with the rows: small)."""
SAVED_TILE = 256
"""The largest side of a saved tile (``tiles/``, shown by ``index.html``)."""
BENCHMARK_KIND = "benchmark"
LAYOUT = re.compile(r"rows\.jsonl|table\.md|sheet\.jpg|index\.html|tiles/[^/]+\.png")
"""The files a benchmark folder holds: what one an older mistyle wrote (no manifest) may hold."""
NOTES_FILE = "README.md"
"""A results folder's notes, written by people (what made the rows, which record cites them): the benchmark
never writes, replaces or deletes it, and it does not make the folder another's."""


@dataclass
class Row:
    method: str
    density: str
    style: str
    rgb_swd: float
    patch_swd: float
    hue_coverage: float
    seconds: float  # making the albedo (path tracing the metric views not included)
    settings: dict  # res, spp, views, quick, optimise_factor: rows compare only at equal settings
    checkpoint: str  # the network's file name and the first 12 hex digits of its SHA-256
    commit: str  # the code's git commit ("+changes" when the tree had uncommitted changes)
    split: str = ""
    structure: float | None = None  # objective.structure (lower is closer); None in rows made before it

    def key(self) -> tuple:
        return self.method, self.density, self.style, json.dumps(self.settings, sort_keys=True)


def metric_views(camera_distance: float, count: int = METRIC_VIEWS) -> list:
    """``count`` views evenly around the orbit, starting at the held-out view."""
    from ..conventions import HELD_OUT_VIEW
    from ..scenes import CameraPath

    return CameraPath(distance=camera_distance).turntable(count, offset=HELD_OUT_VIEW)


def score(
    density,
    albedo,
    style,
    views,
    *,
    res: int,
    spp: int,
    density_scale: float,
    radiance: float,
    denoise: str = "none",
    seed: int = 0,
):
    """``(style_fidelity metrics, images)`` of ``albedo`` on ``density`` path traced from ``views`` (with the
    path tracer's ``seed``), and denoised as ``mistyle-render`` denoises its final images when ``denoise``
    is ``"oidn"``."""
    from ..objective.metrics import style_fidelity
    from ..pathtrace import path_trace

    images, _ = path_trace(
        density, albedo, views, res=res, spp=spp, density_scale=density_scale, light=f"constant:{radiance}", seed=seed
    )
    if denoise == "oidn":
        from ..denoise import denoise as oidn

        images = [oidn(image) for image in images]
    return style_fidelity(images, style), images


def _finite(value) -> float | None:
    return float(value) if value is not None and np.isfinite(value) else None


def checkpoint_id(path) -> str:
    digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()[:12]
    return f"{Path(path).name}:{digest}"


def code_commit(checkout=None) -> str:
    """The git commit of ``checkout`` (default: the package's own checkout), with ``+changes`` where
    tracked files differ from it, or "unknown" outside a checkout."""
    # git finds the checkout the package sits in, if any
    root = Path(__file__).resolve().parent if checkout is None else Path(checkout)
    try:
        commit = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "--short=12", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        ).stdout.strip()
        changed = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return commit + ("+changes" if changed else "")


_NUMBERS = ("rgb_swd", "patch_swd", "hue_coverage", "seconds")


def read_rows(path: Path) -> list[Row]:
    """The rows of ``path`` (none if it does not exist); ``ValueError`` naming the file, the line and the
    fix for a line that is not a row (a damaged or foreign file is never read in part)."""
    path = Path(path)
    if not path.exists():
        return []
    if not path.is_file():
        raise ValueError(f"{path} is not a file; move it away, or choose another --out.")
    known = {field.name for field in fields(Row)}
    rows = []
    for number, raw in enumerate(path.read_bytes().splitlines(), 1):
        try:
            line = raw.decode("utf-8")
            if not line.strip():
                continue
            record = json.loads(line)
            if not isinstance(record, dict):
                raise ValueError("not a JSON object")
            missing = sorted({f.name for f in fields(Row) if f.default is MISSING} - record.keys())
            unknown = sorted(record.keys() - known)
            if missing or unknown:
                raise ValueError(f"missing {missing}" if missing else f"unknown keys {unknown}")
            if not all(isinstance(record[key], (int, float)) for key in _NUMBERS):
                raise ValueError(f"{', '.join(_NUMBERS)} must be numbers")
            if not isinstance(record["settings"], dict):
                raise ValueError("settings must be an object")
            rows.append(Row(**record))
        except (UnicodeDecodeError, ValueError) as error:
            what = "not UTF-8 text" if isinstance(error, UnicodeDecodeError) else str(error).splitlines()[0]
            raise ValueError(
                f"{path}, line {number}, is not a row of mistyle-bench ({what}); the file is damaged: restore it, "
                "delete that line, or move the file away and score again."
            ) from None
    return rows


def write_rows(path: Path, rows: list[Row]) -> None:
    from ..files import atomic_write_bytes

    atomic_write_bytes(path, "".join(json.dumps(asdict(row)) + "\n" for row in rows).encode())


def run(
    out,
    pairs: list,
    method_names: list[str],
    *,
    res: int = 128,
    spp: int = 16,
    denoise: str = "none",
    quick: bool = False,
    resume: bool = False,
    checkpoint=None,
    optimise_factor: float = 2.0,
    cache=None,
    split: str = "",
    log=print,
) -> list[Row]:
    """Score ``method_names`` on ``pairs`` (``splits.split_pairs``), writing rows as they come, then the
    report. Returns every row in ``<out>/rows.jsonl``. ``denoise``: ``"oidn"`` scores the images as
    ``mistyle-render`` shows them (its rows' settings say so; rows made before it have no such key)."""
    from ..files import load_style
    from ..stops import raise_if_requested
    from ..stylizer import Stylizer
    from .methods import METHODS, Context, timed
    from .splits import split_density, split_styles

    check_methods(method_names)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"The output path {out} is a file; choose a folder for --out.")
    out.mkdir(parents=True, exist_ok=True)
    rows_path, tiles = out / ROWS_FILE, out / "tiles"
    rows = read_rows(rows_path)
    settings = {"res": res, "spp": spp, "views": METRIC_VIEWS, "quick": quick, "optimise_factor": optimise_factor}
    if denoise != "none":
        settings["denoise"] = denoise
    if any(_group(row) != _group_of(settings, split) for row in rows):
        from ..progress import status

        status(f"note: {rows_path} also holds rows at other settings; {TABLE_FILE} gives each settings its table")
    stylizer = Stylizer(checkpoint)
    context = Context(
        stylizer,
        metric_views(stylizer.config.render.camera_distance),
        quick=quick,
        optimise_factor=optimise_factor,
    )
    common = {
        "settings": settings,
        "checkpoint": checkpoint_id(stylizer.path),
        "commit": code_commit(),
        "split": split,
    }
    styles = split_styles(split or "heldout")
    for spec in dict.fromkeys(spec for spec, _ in pairs):
        density = split_density(spec, cache)
        for style_name in [name for density_spec, name in pairs if density_spec == spec]:
            style = load_style(styles[style_name]["path"])
            for name in method_names:
                raise_if_requested()
                probe = Row(name, spec.name, style_name, 0.0, 0.0, 0.0, 0.0, **common)
                if resume and any(row.key() == probe.key() and same_network(row, probe) for row in rows):
                    continue
                albedo, seconds = timed(METHODS[name], context, density, style)
                metrics, images = score(
                    density,
                    albedo,
                    style,
                    context.views,
                    res=res,
                    spp=spp,
                    density_scale=context.density_scale,
                    radiance=context.radiance,
                    denoise=denoise,
                )
                row = Row(
                    name,
                    spec.name,
                    style_name,
                    metrics["rgb_swd"],
                    metrics["patch_swd"],
                    metrics["hue_coverage"],
                    seconds,
                    **common,
                    structure=_finite(metrics["structure"]),
                )
                rows = [old for old in rows if old.key() != row.key()] + [row]
                write_rows(rows_path, rows)
                save_tile(tiles, row, images[0])
                log(
                    f"{name:18s} {spec.name:14s} {style_name:34s} RGB {row.rgb_swd:.4f} "
                    f"patch {row.patch_swd:.4f} hue {row.hue_coverage:.2f} "
                    f"structure {row.structure or float('nan'):.3f} {seconds:6.1f} s"
                )
    mixed = mixed_networks(rows)
    if mixed:
        from ..progress import status

        status(
            f"note: {rows_path} holds rows of {', '.join(mixed)} made with more than one network; their medians "
            "in the table mix them (a folder per --checkpoint keeps them apart)"
        )
    report(out)
    return rows


def same_network(row: Row, other: Row) -> bool:
    """Whether ``row`` stands for ``other`` under ``--resume``: the same network, where its method uses one."""
    from .methods import METHODS

    method = METHODS.get(row.method)
    return method is None or not method.uses_network or row.checkpoint == other.checkpoint


def mixed_networks(rows: list[Row]) -> list[str]:
    """The methods that use the network whose rows at one settings hold more than one checkpoint."""
    from .methods import METHODS

    seen: dict[tuple, set] = {}
    for row in rows:
        if row.method in METHODS and METHODS[row.method].uses_network:
            seen.setdefault((row.method, _group(row)), set()).add(row.checkpoint)
    return sorted({method for (method, _), checkpoints in seen.items() if len(checkpoints) > 1})


def check_methods(method_names: list[str]) -> None:
    from .methods import METHODS

    unknown = [name or "''" for name in method_names if name not in METHODS]
    if unknown:
        raise ValueError(f"Unknown method(s) {', '.join(unknown)}; choose from {', '.join(METHODS)}.")
    if len(set(method_names)) < len(method_names):
        raise ValueError(f"--methods names a method twice: {','.join(method_names)}; give each once.")


def folder_files(pairs: list, method_names: list[str]) -> list[str]:
    """The files (relative) a run of ``method_names`` on ``pairs`` may write into its folder."""
    tiles = [f"tiles/{spec.name}__{style}__{name}.png" for spec, style in pairs for name in method_names]
    return [ROWS_FILE, *REPORT_FILES, *tiles]


@contextlib.contextmanager
def owned_folder(out: Path, names: list[str]):
    """Hold the benchmark folder ``out`` for a run that writes ``names`` (relative paths) there, and
    yield its rows: a ``ValueError`` (one line), before anything is written, when it is a file, holds a
    file the benchmark did not write or a damaged ``rows.jsonl``, or another run writes it. The files
    written are recorded in its manifest however the run ends."""
    from ..ownership import adding, adopt_older, check_replaceable, output_lock, read_manifest

    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"The output path {out} is a file; choose a folder for --out.")
    with output_lock(out):
        older = out.is_dir() and read_manifest(out) is None  # an older mistyle's folder: its layout is ours
        check_replaceable(
            out, "--out", also_ours=lambda name: name == NOTES_FILE or (older and LAYOUT.fullmatch(name) is not None)
        )
        rows = read_rows(out / ROWS_FILE)
        adopt_older(out, BENCHMARK_KIND, LAYOUT)
        with adding(out, BENCHMARK_KIND, names, rewritten=names, locked=True):
            yield rows


def _group_of(settings: dict, split: str) -> str:
    return json.dumps({**settings, "split": split or "heldout"}, sort_keys=True)


def _group(row: Row) -> str:
    return _group_of(row.settings, row.split)


def describe_settings(row: Row) -> str:
    """A row's settings and split in words, for a table's heading."""
    shown = ", ".join(f"{key} {value}" for key, value in sorted(row.settings.items()))
    return f"{shown}; split {row.split or 'heldout'}"


# ---------------------------------------------------------------------------- report
NOISE_BASELINE = "smooth_noise"
"""The training-free baseline every stylization claim is also measured against (``methods``)."""
TUNED_NOISE_BASELINE = "tuned_noise"
"""The strongest training-free field (``methods``): the bar for a claim that patterns are the style's."""
RATIO_BASELINES = (("uniform", "uniform"), (NOISE_BASELINE, "noise"), (TUNED_NOISE_BASELINE, "tuned"))
"""``(method, suffix)``: the baselines ``summary`` divides each row by, on the same pair and settings."""


def summary(rows: list[Row]) -> dict:
    """Per method (in ``METHODS`` order, then others): medians of the metrics and of each SWD's ratio to
    each of ``RATIO_BASELINES`` on the same pair and settings (``<metric>_x_<suffix>``, NaN where that
    baseline has no rows), how many pairs have a structure closer than the noise baselines'
    (``structure_beats_<suffix>`` of ``structure_pairs_<suffix>``), the number of pairs, and how many
    of them beat the uniform baseline on both SWDs."""
    from .methods import METHODS

    def on_pair(row: Row) -> tuple:
        return (row.density, row.style, json.dumps(row.settings, sort_keys=True))

    baselines = {name: {on_pair(row): row for row in rows if row.method == name} for name, _ in RATIO_BASELINES}
    order = list(METHODS) + sorted({row.method for row in rows} - set(METHODS))
    result = {}
    for method in order:
        mine = [row for row in rows if row.method == method]
        if not mine:
            continue
        entry = {
            key: float(np.median([getattr(row, key) for row in mine]))
            for key in ("rgb_swd", "patch_swd", "hue_coverage", "seconds")
        }
        measured = [row for row in mine if row.structure is not None]
        entry["structure"] = float(np.median([row.structure for row in measured])) if measured else float("nan")
        for name, suffix in RATIO_BASELINES:
            matched = [(row, baselines[name].get(on_pair(row))) for row in mine]
            matched = [(row, base) for row, base in matched if base is not None]
            for key in ("rgb_swd", "patch_swd"):
                entry[f"{key}_x_{suffix}"] = (
                    float(np.median([getattr(row, key) / getattr(base, key) for row, base in matched]))
                    if matched
                    else float("nan")
                )
            if name == "uniform":
                entry["beats_uniform"] = sum(
                    row.rgb_swd < base.rgb_swd and row.patch_swd < base.patch_swd for row, base in matched
                )
                entry["uniform_pairs"] = len(matched)
                continue
            against = [(row, base) for row, base in matched if row.structure is not None and base.structure is not None]
            entry[f"structure_pairs_{suffix}"] = len(against)
            entry[f"structure_beats_{suffix}"] = sum(row.structure < base.structure for row, base in against)
        entry["pairs"] = len(mine)
        result[method] = entry
    return result


def table(rows: list[Row]) -> str:
    """The medians of ``summary`` as a Markdown table."""
    lines = [
        "| method | RGB SWD | x uniform | x noise | x tuned | patch SWD | x uniform | x noise | x tuned | "
        "hue coverage | structure | structure < noise | structure < tuned | beats uniform | seconds | pairs |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]

    def ratio(value: float) -> str:
        return "n/a" if np.isnan(value) else f"{value:.2f}"

    def closer(m: dict, suffix: str) -> str:
        pairs = m[f"structure_pairs_{suffix}"]
        return f"{m[f'structure_beats_{suffix}']}/{pairs}" if pairs else "n/a"

    def beats(m: dict) -> str:
        return f"{m['beats_uniform']}/{m['uniform_pairs']}" if m["uniform_pairs"] else "n/a"

    for method, m in summary(rows).items():
        structure = "n/a" if np.isnan(m["structure"]) else f"{m['structure']:.3f}"
        lines.append(
            f"| {method} | {m['rgb_swd']:.4f} | {ratio(m['rgb_swd_x_uniform'])} | {ratio(m['rgb_swd_x_noise'])} | "
            f"{ratio(m['rgb_swd_x_tuned'])} | {m['patch_swd']:.4f} | {ratio(m['patch_swd_x_uniform'])} | "
            f"{ratio(m['patch_swd_x_noise'])} | {ratio(m['patch_swd_x_tuned'])} | {m['hue_coverage']:.2f} | "
            f"{structure} | {closer(m, 'noise')} | {closer(m, 'tuned')} | {beats(m)} | "
            f"{m['seconds']:.1f} | {m['pairs']} |"
        )
    return "\n".join(lines) + "\n"


def report(out) -> str:
    """Rewrite ``table.md`` (all pairs, then each density's; one table per settings when the rows hold
    several), ``sheet.jpg`` and ``index.html`` in ``out`` from its rows; returns the table."""
    from ..files import atomic_write_bytes
    from ..pages import write_index

    out = Path(out)
    rows = read_rows(out / ROWS_FILE)
    groups: dict[str, list[Row]] = {}
    for row in rows:
        groups.setdefault(_group(row), []).append(row)
    if len(groups) > 1:
        text = (
            f"{ROWS_FILE} holds rows at {len(groups)} different settings; each has its own table below "
            "(rows compare only at equal settings).\n"
        )
        for members in groups.values():
            pairs = len({(row.density, row.style) for row in members})
            text += f"\n## {describe_settings(members[0])}: {pairs} pairs\n\n" + _tables(members)
    else:
        text = _tables(rows)
    atomic_write_bytes(out / TABLE_FILE, text.encode())
    lines = [f"{len(rows)} rows; the table is {TABLE_FILE}"]
    tiles = out / "tiles"
    if tiles.is_dir() or not (out / SHEET_FILE).exists():
        write_sheet(rows, tiles, out / SHEET_FILE)
    else:  # a checkout keeps the sheet, not its tiles (they are not committed): an empty sheet would replace it
        lines.append(f"{SHEET_FILE} kept as it was: its tiles are not in this checkout")
    if len(groups) > 1:
        lines.append(f"the rows hold {len(groups)} different settings; the table gives each its own")
    write_index(out, "mistyle: style-fidelity benchmark", lines)
    return text


def _tables(rows: list[Row]) -> str:
    """The table of ``rows`` (one settings), then one per density when there are several."""
    text = table(rows)
    densities = list(dict.fromkeys(row.density for row in rows))
    if len(densities) > 1:  # a method can lead on one kind of density and not on another
        text += "".join(f"\n### {name}\n\n" + table([r for r in rows if r.density == name]) for name in densities)
    return text


def tile_path(folder: Path, row: Row) -> Path:
    return folder / f"{row.density}__{row.style}__{row.method}.png"


def save_tile(folder: Path, row: Row, image: np.ndarray) -> None:
    """The first metric view of a row, on display, as a PNG of at most ``SAVED_TILE``^2 (the render's own
    pixels at the default scoring, so that ``index.html`` shows the strokes a user sees)."""
    from PIL import Image

    from ..files import write_png
    from ..tone import display

    shown = Image.fromarray((display(image) * 255 + 0.5).astype(np.uint8))
    if max(shown.size) > SAVED_TILE:
        shown = shown.resize((SAVED_TILE, SAVED_TILE), Image.LANCZOS)
    folder.mkdir(parents=True, exist_ok=True)
    write_png(tile_path(folder, row), np.asarray(shown, np.float32) / 255, srgb=False)


def _sheet_tile(path: Path, side: int) -> np.ndarray:
    """A saved tile at ``side``^2 (older folders hold tiles of ``TILE``^2)."""
    from PIL import Image

    from ..files import load_style

    tile = load_style(path)
    if tile.shape[:2] == (side, side):
        return tile
    shown = Image.fromarray((tile * 255 + 0.5).astype(np.uint8)).resize((side, side), Image.LANCZOS)
    return np.asarray(shown, np.float32) / 255


def write_sheet(rows: list[Row], tiles: Path, path: Path, side: int = TILE) -> None:
    """Per (density, style): the style, then each method's tile (grey where none was saved), ``side``
    pixels each (``SAVED_TILE``: large enough to see strokes). A method with no saved tile at all is
    left out: tiles are not committed, so a folder scored again on a fresh checkout has rows but no
    tiles for the methods it did not score again."""
    from PIL import Image, ImageDraw

    from ..files import atomic_output, load_style
    from ..model.features import square_style
    from .splits import split_styles

    pairs = list(dict.fromkeys((row.density, row.style) for row in rows))
    if not pairs:
        return
    methods = [method for method in summary(rows) if any(tiles.glob(f"*__{method}.png"))]
    styles = {}
    for split in dict.fromkeys(row.split or "heldout" for row in rows):
        styles.update(split_styles(split))
    canvas = np.full((len(pairs) * side + 16, (len(methods) + 1) * side, 3), 1.0, np.float32)
    for index, (density, style) in enumerate(pairs):
        cells = [square_style(load_style(styles[style]["path"]), side).permute(1, 2, 0).numpy()]
        for method in methods:
            tile = tiles / f"{density}__{style}__{method}.png"
            cells.append(_sheet_tile(tile, side) if tile.exists() else np.full((side, side, 3), 0.5, np.float32))
        canvas[16 + index * side : 16 + (index + 1) * side] = np.concatenate(cells, axis=1)
    image = Image.fromarray((canvas * 255 + 0.5).astype(np.uint8))
    draw = ImageDraw.Draw(image)
    for column, name in enumerate(["style"] + methods):
        draw.text((column * side + 4, 2), name, fill="black")
    for index, (density, _) in enumerate(pairs):
        draw.text((4, 16 + index * side + 4), density, fill="white")
    with atomic_output(path) as temporary:
        image.save(temporary, format="JPEG", quality=80)  # the sheets of results/ are committed: 0.8x the bytes of 88
