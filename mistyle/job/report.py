"""An output's ``report.json`` and sheet (``write_report``), and a chunk of a sequence merged into its
folder (``merge_chunk``)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from .spec import Job, check_same_settings, log, settings_record

METRIC_KEYS = ("rgb_swd", "patch_swd", "hue_coverage", "structure", "swd_final", "hist_final", "swd_layer")
SHEET_LABELS = ("style", "the network (fast layer)", "the output (path traced)")
"""``sheet.png``'s panels, whole runs and merged chunks alike: the style, what the network alone gives, and
what was path traced (the default output: a look fitted on the frames)."""


def write_report(job: Job, stylized, images, layer_images, report: dict) -> None:
    """Style metrics of every image against the style, ``report.json``, ``sheet.png`` and a summary line;
    a chunk merged into a sequence's folder (``job.merged``) measures each frame alone, which is all
    ``merge_chunk`` keeps, and leaves the folder's files to it.

    A metric that cannot be computed is ``null`` in the report, with a note, also shown on the console:
    the style metrics of images that see no medium (the pipeline refuses a render where none does, and
    names why each image does not: ``Pipeline.check_images``), ``patch_swd`` when no 5x5 patch lies inside it."""
    from ..files import atomic_write_bytes
    from ..objective.metrics import foreground_mask, style_distance, style_fidelity
    from ..outputs import REPORT_FILE
    from ..pages import SHEET_FILE, write_sheet
    from ..tone import display

    style = stylized.target
    started = time.perf_counter()
    visible = [image for image in images if foreground_mask(image).any()]
    if visible and len(visible) < len(images):
        unseen = len(images) - len(visible)
        note = f"{unseen} of {len(images)} image(s) see no medium; the style metrics are of the others"
        job.notes.append(note)
        log(f"note: {note}")
    if not visible:
        note = "no pixel of the final render sees the medium; the style metrics are left out"
        job.notes.append(note)
        log(f"note: {note}")
    if job.merged:  # the folder's report, sheet and index give each frame's metrics alone: merge_chunk
        report["frames"] = {
            f"{job.first + index:04d}": frame_metrics(image, style) for index, image in enumerate(images)
        }
        report["metrics_seconds"] = time.perf_counter() - started
        return
    if visible:
        final = [style_distance(image, style) for image in visible]
        report["swd_final"] = float(np.mean([distance["swd"] for distance in final]))
        report["hist_final"] = float(np.mean([distance["hist"] for distance in final]))
        seen = [image for image in layer_images if foreground_mask(image).any()]
        report["swd_layer"] = float(np.mean([style_distance(image, style)["swd"] for image in seen])) if seen else None
        report.update(style_fidelity(visible, style))
    else:
        report.update(dict.fromkeys(METRIC_KEYS))
    for key in METRIC_KEYS:
        if report.get(key) is not None and not np.isfinite(report[key]):
            report[key] = None
            job.notes.append(f"{key} left out: too few pixels see the medium to measure it")
    report["metrics_seconds"] = time.perf_counter() - started
    atomic_write_bytes(job.out / REPORT_FILE, (json.dumps(report, indent=1) + "\n").encode())
    seconds = sum(
        report.get(key, 0.0) for key in ("stylize_seconds", "look_seconds", "refine_seconds", "render_seconds")
    )

    def shown(key, digits):
        return "-" if report[key] is None else f"{report[key]:.{digits}f}"

    refinement, settings = stylized.refinement, job.pipeline.settings
    if stylized.look is not None:
        key_frames = ",".join(map(str, stylized.look.meta["key_frames"]))
        stage = f"a look fitted on key frames {key_frames}" if job.sequence else "a look fitted on the frame"
    else:
        stage = f"refine {refinement.layer_steps}+{refinement.path_steps} steps"
    lines = [
        f"{job.output.density.path.name} x {job.output.style.describe(names_only=True)}"[:110],
        f"RGB SWD {shown('rgb_swd', 4)}   patch SWD {shown('patch_swd', 4)}   hue coverage {shown('hue_coverage', 2)}",
        f"strength {settings.strength:g}, {stage}, {settings.render.res}^2 x {settings.render.spp} spp, "
        f"{seconds:.1f} s",
    ]
    write_sheet(
        job.out / SHEET_FILE,
        list(zip(SHEET_LABELS, (style, display(layer_images[0]), display(images[0])))),
        lines,
    )
    keys = (
        "stylize_seconds",
        "look_seconds",
        "refine_seconds",
        "render_seconds",
        "rgb_swd",
        "patch_swd",
        "hue_coverage",
    )
    print(json.dumps({key: report[key] for key in keys if key in report}))


def check_mergeable(job: Job) -> None:
    """``ValueError`` when ``job``'s folder holds frames of another sequence or look: chunks merge only
    with chunks of the same density and look (or style)."""
    from ..outputs import REPORT_FILE, is_mistyle_output

    folder = job.output.folder
    if not is_mistyle_output(folder) or not (folder / REPORT_FILE).is_file():
        return
    held = json.loads((folder / REPORT_FILE).read_text()).get("inputs", {})
    ours = inputs_record(job)
    for record in (held, ours):  # the same folder of frames, however the command named it
        record["density"] = str(Path(record.get("density", "")).resolve())
    for key, what in (("density", "density"), ("look_sha256", "look"), ("style", "style"), ("shape_zyx", "grid size")):
        if held.get(key) != ours.get(key):
            raise ValueError(
                f"{folder} holds frames of another {what} ({held.get(key)}); chunks merge only with chunks of the "
                "same density and look. Choose another --out, or remove that folder first."
            )
    check_same_settings(settings_record(job.pipeline.settings), folder, "a chunk merges into it")


def frame_metrics(image: np.ndarray, style: np.ndarray) -> dict:
    """One frame's style metrics (``objective.metrics.style_fidelity``), None where they cannot be measured."""
    from ..objective.metrics import foreground_mask, style_fidelity

    if not foreground_mask(image).any():
        return dict.fromkeys(FRAME_METRICS)
    metrics = style_fidelity([image], style)
    return {key: (float(value) if value is not None and np.isfinite(value) else None) for key, value in metrics.items()}


FRAME_METRICS = ("rgb_swd", "patch_swd", "hue_coverage", "structure")


def merge_chunk(job: Job, folder: Path) -> None:
    """Move a chunk's files from ``job.out`` into ``folder`` (``ownership.merge_files``), then write the folder's
    ``report.json`` (every frame present, each with its metrics; the chunks that made them), its video,
    ``sheet.png`` (its first frame) and ``index.html``. Two chunks give the files one run gives.
    The folder's manifest takes the files in, so a later chunk or ``--overwrite`` knows them for mistyle's."""
    from ..outputs import REPORT_FILE
    from ..ownership import writing
    from ..pages import INDEX_FILE, SHEET_FILE

    names = [p.name for p in job.out.iterdir() if p.is_file()]
    with writing(folder, "sequence", names + [REPORT_FILE, "sequence.mp4", "sequence.gif", SHEET_FILE, INDEX_FILE]):
        _merge_chunk_files(job, folder)


def _merge_chunk_files(job: Job, folder: Path) -> None:
    from ..files import atomic_write_bytes, read_png, write_gif, write_mp4
    from ..outputs import REPORT_FILE
    from ..ownership import merge_files
    from ..pages import SHEET_FILE, write_index, write_sheet

    chunk, render = job.report, job.pipeline.settings.render
    merge_files(job.out, folder)
    old = json.loads((folder / REPORT_FILE).read_text()) if (folder / REPORT_FILE).is_file() else {}
    frames = {**old.get("frames", {}), **chunk["frames"]}
    frames = dict(sorted(frames.items()))
    done = set(chunk["frames"])
    timings = {key: chunk[key] for key in ("stylize_seconds", "refine_seconds", "render_seconds") if key in chunk}
    this = {"frames": [job.first, job.first + len(job.frames.densities) - 1], **timings}
    for key in ("temporal_flicker", "temporal_flicker_unwarped"):
        if key in chunk:
            this[key] = chunk[key]
    chunks = [
        c
        for c in old.get("chunks", [])
        if not set(f"{i:04d}" for i in range(c["frames"][0], c["frames"][1] + 1)) <= done
    ]
    report = {
        "inputs": {**chunk["inputs"], "frames": len(frames), "frames_in_sequence": job.total_frames},
        "notes": list(dict.fromkeys(old.get("notes", []) + job.notes)),
        "frames": frames,
        "chunks": sorted(chunks + [this], key=lambda c: c["frames"][0]),
    }
    for key in FRAME_METRICS:
        values = [entry[key] for entry in frames.values() if entry.get(key) is not None]
        report[key] = float(np.mean(values)) if values else None
    stems = [f"sequence_{index}" for index in frames]
    shown = [read_png(folder / f"{stem}.png") for stem in stems if (folder / f"{stem}.png").is_file()]
    if len(shown) > 1:
        report["video"] = [
            write_mp4(folder / "sequence.mp4", shown, job.spec.fps).name,
            write_gif(folder / "sequence.gif", shown, job.spec.fps).name,
        ]
    first = stems[0]
    style = job.look.style if job.look is not None else job.style.images[0]
    # The look's own record of its style, not its file's name: a farm's workers hold it under another.
    described = (
        job.look.meta.get("style", "a look") if job.look is not None else job.output.style.describe(names_only=True)
    )
    lines = [
        f"{job.output.density.path.name} x {described}"[:110],
        f"{len(frames)} of {job.total_frames} frames; mean RGB SWD {_shown(report, 'rgb_swd', 4)}, "
        f"patch SWD {_shown(report, 'patch_swd', 4)}, hue coverage {_shown(report, 'hue_coverage', 2)}",
        f"first frame {frames and next(iter(frames))} shown; {render.res}^2 x {render.spp} spp",
    ]
    write_sheet(
        folder / SHEET_FILE,
        list(
            zip(
                SHEET_LABELS,
                (
                    style,
                    read_png(folder / f"{first}_network_layer.png") / 255.0,
                    read_png(folder / f"{first}.png") / 255.0,
                ),
            )
        ),
        lines,
    )
    atomic_write_bytes(folder / REPORT_FILE, (json.dumps(report, indent=1) + "\n").encode())  # the index lists it
    write_index(
        folder,
        f"mistyle: {len(frames)} frame{'s' if len(frames) != 1 else ''} of {job.output.density.name}",
        [
            f"frame {index}: RGB SWD {_shown(entry, 'rgb_swd', 4)}, patch SWD {_shown(entry, 'patch_swd', 4)}, "
            f"hue coverage {_shown(entry, 'hue_coverage', 2)}"
            for index, entry in frames.items()
        ],
    )
    report["files"] = sorted(p.name for p in folder.iterdir() if p.is_file() and not p.name.startswith("."))
    atomic_write_bytes(folder / REPORT_FILE, (json.dumps(report, indent=1) + "\n").encode())
    print(json.dumps({"frames": this["frames"], **{key: report[key] for key in FRAME_METRICS}}))


def _shown(record: dict, key: str, digits: int) -> str:
    return "-" if record.get(key) is None else f"{record[key]:.{digits}f}"


def inputs_record(job: Job) -> dict:
    spec, pipeline = job.spec, job.pipeline
    refinement = pipeline.look_refinement() if job.look is not None else pipeline.refinement(len(job.frames.densities))
    return {
        "density": str(job.output.density.path),
        "mesh": job.output.density.mesh,
        "grid": spec.grid,
        "style": job.look.meta.get("style", "a look") if job.look is not None else job.output.style.describe(),
        "frames": len(job.frames.densities),
        "shape_zyx": list(job.frames.densities[0].shape),
        "checkpoint": str(pipeline.stylizer.path),
        "look_sha256": None if job.look is None else job.look.meta.get("file_sha256"),
        **settings_record(pipeline.settings),
        "density_scale": pipeline.density_scale,
        "refine_steps": refinement.layer_steps,
        "refine_path_steps": refinement.path_steps,
        "views": len(job.views),
    }
