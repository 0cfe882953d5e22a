"""What one output is: its inputs, loaded and checked (``Job``), how they are read and its files written beyond
the pipeline's settings (``OutputSpec``), and the settings its ``report.json`` records (``SETTING_OPTIONS``)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

SETTING_OPTIONS = {
    "res": "--res",
    "spp": "--spp",
    "denoise": "--denoise",
    "max_depth": "--max-depth",
    "light": "--light",
    "coat_ior": "--coat",
    "view": "--view",
    "turntable": "--turntable",
    "strength": "--strength",
    "scale_structures": "--scale-structures",
    "working_size": "--working-size",
    "colour_match": "--no-colour-match",
}
"""The options that decide how an output's frames look, as ``report.json`` records them: chunks merged
into one folder, and outputs kept by ``--resume``, must agree on all of them."""


@dataclass(frozen=True)
class OutputSpec:
    """How an output's inputs are read and its files written, beyond what ``PipelineSettings`` decide."""

    grid: str | None = None  # the grid read from ..vdb densities (None: 'density', or the only one)
    up: str | None = None  # the up axis of the densities (None: what a .vdb file records, else y)
    mesh_res: int = 64  # voxels along a mesh's longest side
    fps: int = 12  # the videos' frame rate
    vdb: bool = False  # also write volume.vdb for densities that are not .vdb files


def settings_record(settings) -> dict:
    """The ``SETTING_OPTIONS`` of ``settings`` (``pipeline.PipelineSettings``) as ``report.json`` records them
    (tuples become lists)."""
    render = settings.render
    record = {
        "res": render.res,
        "spp": render.spp,
        "denoise": render.denoise,
        "max_depth": render.max_depth,
        "light": render.light,
        "coat_ior": render.coat_ior,
        "view": render.view,
        "turntable": render.turntable,
        "strength": settings.strength,
        "scale_structures": settings.scale_structures,
        "working_size": settings.working_size,
        "colour_match": settings.colour_match,
    }
    assert record.keys() == SETTING_OPTIONS.keys()
    return json.loads(json.dumps(record))


def log(message: str) -> None:
    from ..progress import status

    status(message)


def check_same_settings(record: dict, folder: Path, why: str, other_fix: str = "") -> None:
    """``ValueError`` naming the first option whose value in ``record`` (``settings_record``) differs from the
    one ``folder``'s render used."""
    from ..outputs import REPORT_FILE

    try:
        held = json.loads((folder / REPORT_FILE).read_text()).get("inputs", {})
    except (OSError, ValueError, AttributeError):
        raise ValueError(
            f"{folder / REPORT_FILE} cannot be read, so the render settings of {folder} are unknown; "
            f"{other_fix or 'remove that folder'}, or choose another --out."
        ) from None
    for key, value in record.items():
        if key in held and held[key] != value:
            option, fixes = SETTING_OPTIONS[key], ", ".join(filter(None, [other_fix, "or choose another --out"]))
            raise ValueError(
                f"{folder} was rendered with {option} {held[key]} and this run asks for {value}; {why} only with the "
                f"same settings: give {option} {held[key]}, {fixes}."
            )


@dataclass
class Job:
    """One output's inputs, loaded and checked before any heavy work (``load_job``), and where it goes."""

    spec: OutputSpec
    output: object  # outputs.Output: the (density, style) pair and its folder
    pipeline: object  # pipeline.Pipeline
    style: object  # style.Style: the output's style, loaded once
    frames: object  # pipeline.Frames
    names: list[str]
    views: list  # scenes.View
    coat_mesh: tuple | None = None  # (vertices, faces) placed in the medium box, for --mesh with --coat
    coat_mesh_path: Path | None = None
    transforms: list | None = None  # per frame, the vdb.VdbTransform of a .vdb density
    sources: list | None = None  # per frame, the .vdb file it was read from (its other grids travel into volume.vdb)
    up: str = "y"  # the world up axis volume.vdb is written in (conventions.UP_AXES)
    notes: list[str] = field(default_factory=list)
    out: Path | None = None  # the staging folder of the run (``ownership.staged_directory``), set in ``run``
    first: int = 0  # the index of the first frame in the whole sequence (``--frames``)
    total_frames: int = 1  # the whole sequence's frames
    look: object = None  # look.Look: stylize with it instead of the style
    merged: bool = False  # the output merges frame by frame into its folder (``ownership.chunk_staging``)
    report: dict = field(default_factory=dict)

    @property
    def sequence(self) -> bool:
        return self.frames.sequence or self.merged
