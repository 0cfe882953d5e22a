"""A training run's folder: the files it may hold (``mistyle.ownership``'s manifest, kind ``train``), the
check before a run writes into it, and its records (``RunLog``: ``metrics.jsonl`` and TensorBoard's
events), trimmed to the step a run resumes from."""

from __future__ import annotations

import json
import re
from pathlib import Path

from ..files import atomic_write_bytes

RUN_KIND = "train"
RUN_LAYOUT = re.compile(
    r"config\.toml|metrics\.jsonl|(last|final|best|chosen)\.pt|steps/step_\d{6}\.pt|previews/step_\d{6}\.png"
    r"|tb/events\.out\.tfevents\.[^/]+|baseline\.json"
)
"""The files of a run folder: what one an older mistyle wrote (no manifest) may hold to be resumed."""
TENSORBOARD_FILE = re.compile(r"tb/events\.out\.tfevents\.[^/]+")
"""TensorBoard's event files: each writer makes a new one (never replacing a file), named as it starts."""
RUN_FILES = ["config.toml", "metrics.jsonl", "last.pt", "final.pt", "best.pt"]
"""The files a run writes whose names are known before it starts."""


def check_run_folder(out: Path, resume: bool) -> None:
    """``ValueError`` (one line) unless ``out`` may take this run: missing, or a folder holding only
    mistyle's files (with ``resume``, also a run folder an older mistyle wrote)."""
    from ..ownership import check_replaceable, read_manifest

    if out.exists() and not out.is_dir():
        raise ValueError(f"The output path {out} is a file; choose a folder for --out.")
    older = resume and out.is_dir() and read_manifest(out) is None
    layout = RUN_LAYOUT if older else TENSORBOARD_FILE
    check_replaceable(out, "--out", also_ours=lambda name: layout.fullmatch(name) is not None)


def record_files(out: Path, **changes) -> None:
    """``ownership.update_manifest`` of the run folder ``out`` (kind ``train``)."""
    from ..ownership import update_manifest

    update_manifest(out, RUN_KIND, **changes)


def trim_metrics(out: Path, step: int) -> list[dict]:
    """Drop records of ``out/metrics.jsonl`` past the restored ``step`` (written after the checkpoint a killed
    run resumed from; a new run keeps none) and a last line cut short by a kill; the records kept.
    ``ValueError`` naming the file and line for any other line that is not a record."""
    path = out / "metrics.jsonl"
    if not path.is_file():
        return []
    lines = path.read_bytes().splitlines()
    kept = []
    for number, raw in enumerate(lines, 1):
        try:
            record = json.loads(raw.decode("utf-8")) if raw.strip() else None
            if record is not None and not (isinstance(record, dict) and isinstance(record.get("step"), int)):
                raise ValueError("not a record with a step")
        except (UnicodeDecodeError, ValueError):
            if number == len(lines):
                continue  # the line a killed run was appending
            raise ValueError(
                f"{path}, line {number}, is not a training record; the file is damaged: restore it, or "
                "delete that line, and resume again."
            ) from None
        if record is not None and step > 0 and record["step"] <= step:
            kept.append(record)
    atomic_write_bytes(path, "".join(json.dumps(record) + "\n" for record in kept).encode())
    return kept


class RunLog:
    """A run's records: ``metrics.jsonl`` (one object per logged step) and TensorBoard's events in ``tb/``,
    written by the first process of a run only (``rank`` 0)."""

    def __init__(self, out: Path):
        self.out, self._writer = out, None

    def tensorboard(self):
        if self._writer is None:
            from torch.utils.tensorboard import SummaryWriter

            self._writer = SummaryWriter(str(self.out / "tb"))
        return self._writer

    def record(self, record: dict, rank: int = 0) -> None:
        if rank != 0:
            return
        with open(self.out / "metrics.jsonl", "a") as handle:
            handle.write(json.dumps(record) + "\n")
        writer = self.tensorboard()
        for key, value in record.items():
            if key != "step":
                writer.add_scalar(("val/" if key.startswith("val_") else "train/") + key, value, record["step"])

    def images(self, step: int, visuals: dict, rank: int = 0) -> None:
        """A training step's style, views and their masks (the first batch item's)."""
        from ..objective.masks import render_mask
        from ..tone import tone_map

        if rank != 0:
            return
        writer, images = self.tensorboard(), visuals["images"][0]
        writer.add_image("train/style", visuals["styles"][0].clamp(0, 1), step)
        writer.add_images("train/views", tone_map(images).clamp(0, 1), step)
        writer.add_images("train/masks", render_mask(images), step)

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
