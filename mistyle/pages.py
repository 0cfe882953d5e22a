"""Pictures and pages a person looks at: a render's ``sheet.png`` and a folder's ``index.html``.

``write_sheet``: style | fast layer | final render side by side, with lines of text (the metrics)
under them. ``write_grid``: the experiments' figures, rows of labelled tiles. ``write_index``: one
HTML page for a batch of renders or an experiment's output folder, listing what is in it -- each
sub-folder's ``sheet.png`` with its ``report.json`` metrics, then the folder's images, videos,
tables (``*_table.md``, shown) and data files and notes (linked) -- all as relative links, so the
folder can be moved or served as it is. The experiments write one for their output folder
(``docs/index.html`` by default).
"""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".gif")
VIDEO_SUFFIXES = (".mp4",)
TABLE_ENDINGS = ("_table.md",)  # written by the experiments; shown in the page, other .md files are linked
DATA_SUFFIXES = (".md", ".json", ".jsonl", ".csv", ".exr", ".vol", ".vdb", ".xml", ".npy", ".txt")
SHEET_FILE = "sheet.png"
INDEX_FILE = "index.html"
EXPERIMENTS_TITLE = "mistyle: figures and tables"  # the experiments' index of their output folder (docs/)
REPORT_METRICS = ("rgb_swd", "patch_swd", "hue_coverage", "stylize_seconds", "refine_seconds", "render_seconds")


def _panel(image: np.ndarray, size: int):
    """A display-encoded ``(H, W, 3)`` image in [0, 1] fitted into a ``size`` square on black."""
    from PIL import Image

    picture = Image.fromarray((np.clip(image, 0.0, 1.0) * 255 + 0.5).astype(np.uint8))
    scale = size / max(picture.size)
    # Small renders are enlarged without smoothing, so their pixels stay visible as pixels.
    picture = picture.resize(
        (max(1, round(picture.width * scale)), max(1, round(picture.height * scale))),
        Image.LANCZOS if scale < 1 else Image.NEAREST,
    )
    square = Image.new("RGB", (size, size))
    square.paste(picture, ((size - picture.width) // 2, (size - picture.height) // 2))
    return square


def write_sheet(path, panels: list[tuple[str, np.ndarray]], lines: list[str], size: int = 256) -> Path:
    """``panels = [(label, display image in [0, 1])]`` side by side, labels above and ``lines`` under."""
    from PIL import Image, ImageDraw

    from .files import atomic_output

    line_height, top = 14, 18
    sheet = Image.new("RGB", (size * len(panels), top + size + 6 + line_height * len(lines)), "white")
    draw = ImageDraw.Draw(sheet)
    for index, (label, image) in enumerate(panels):
        sheet.paste(_panel(image, size), (index * size, top))
        draw.text((index * size + 4, 3), label, fill="black")
    for row, line in enumerate(lines):
        draw.text((4, top + size + 4 + row * line_height), line, fill="black")
    with atomic_output(path) as tmp:
        sheet.save(tmp, format="PNG")
    return Path(path)


def write_grid(path, rows: list[list[tuple[np.ndarray, str]]], size: int = 128) -> Path:
    """Rows of ``(display image in [0, 1], label)`` tiles, each fitted into a ``size`` square with its
    label above it; PNG, or JPEG (quality 88) when ``path`` ends in ``.jpg``."""
    from PIL import Image, ImageDraw

    from .files import atomic_output

    label = 14
    columns = max(len(row) for row in rows)
    sheet = Image.new("RGB", (size * columns, (size + label) * len(rows)), "white")
    draw = ImageDraw.Draw(sheet)
    for r, row in enumerate(rows):
        for c, (image, text) in enumerate(row):
            sheet.paste(_panel(image, size), (c * size, r * (size + label) + label))
            draw.text((c * size + 3, r * (size + label) + 1), text, fill="black")
    jpeg = Path(path).suffix.lower() in (".jpg", ".jpeg")
    with atomic_output(path) as tmp:
        sheet.save(tmp, format="JPEG" if jpeg else "PNG", **({"quality": 88} if jpeg else {}))
    return Path(path)


def _metrics_line(report: dict) -> str:
    return ", ".join(f"{key} {report[key]:.4g}" for key in REPORT_METRICS if isinstance(report.get(key), (int, float)))


def write_index(folder, title: str, notes: list[str] | None = None) -> Path:
    """``folder/index.html`` linking everything in ``folder`` a person would open (see module doc)."""
    from .files import atomic_write_bytes

    folder = Path(folder)
    parts = [
        f"<!doctype html><meta charset='utf-8'><title>{html.escape(title)}</title>",
        "<style>body{font-family:sans-serif;margin:1em}img{max-width:100%;border:1px solid #ccc}"
        "figure{display:inline-block;margin:.5em;vertical-align:top;max-width:46%}"
        "figcaption{font-size:small}pre{background:#f4f4f4;padding:.5em;overflow:auto}</style>",
        f"<h1>{html.escape(title)}</h1>",
    ]
    parts += [f"<p>{html.escape(note)}</p>" for note in notes or []]

    def link(path: Path) -> str:
        return html.escape(path.relative_to(folder).as_posix(), quote=True)

    renders = sorted(
        p for p in folder.iterdir() if p.is_dir() and not p.name.startswith(".") and (p / SHEET_FILE).is_file()
    )
    if renders:
        parts.append("<h2>Renders</h2>")
        for render in renders:
            report_path = render / "report.json"
            report = json.loads(report_path.read_text()) if report_path.is_file() else {}
            caption = html.escape(render.name) + (f"<br>{html.escape(_metrics_line(report))}" if report else "")
            parts.append(
                f"<figure><a href='{link(render)}/'><img src='{link(render / SHEET_FILE)}' loading='lazy'></a>"
                f"<figcaption>{caption}</figcaption></figure>"
            )
    files = sorted(p for p in folder.iterdir() if p.is_file() and not p.name.startswith(".") and p.name != INDEX_FILE)
    images = [p for p in files if p.suffix.lower() in IMAGE_SUFFIXES]
    if images:
        parts.append("<h2>Figures</h2>")
        parts += [
            f"<figure><a href='{link(p)}'><img src='{link(p)}' loading='lazy'></a>"
            f"<figcaption>{html.escape(p.name)}</figcaption></figure>"
            for p in images
        ]
    videos = [p for p in files if p.suffix.lower() in VIDEO_SUFFIXES]
    if videos:
        parts.append("<h2>Videos</h2>")
        parts += [
            f"<figure><video src='{link(p)}' controls loop muted></video><figcaption>{html.escape(p.name)}"
            "</figcaption></figure>"
            for p in videos
        ]
    tables = [p for p in files if p.name.endswith(TABLE_ENDINGS)]
    for table in tables:
        parts.append(f"<h2>{html.escape(table.name)}</h2><pre>{html.escape(table.read_text())}</pre>")
    data = [p for p in files if p.suffix.lower() in DATA_SUFFIXES and p not in tables]
    if data:
        parts.append(
            "<h2>Data</h2><ul>"
            + "".join(f"<li><a href='{link(p)}'>{html.escape(p.name)}</a></li>" for p in data)
            + "</ul>"
        )
    return atomic_write_bytes(folder / INDEX_FILE, "\n".join(parts).encode())
