"""What one ``render_final`` run makes: an output per (density, style) pair, named after its inputs.

``--density``/``--mesh`` and ``--style`` take several values (or shell globs); a ``--style``
folder stands for the images in it, and a ``--density`` folder for one sequence of frames (as
before). ``--mix a.png:0.7 b.png:0.3`` is one style made of several. A single pair is written to
``--out`` itself; several go to ``--out/{density}__{style}/`` with an ``index.html`` beside them.
An output that already exists is refused unless ``--overwrite`` is given, before any work starts.

``--overwrite`` replaces only what mistyle wrote (``ownership``): an output folder whose manifest
lists every file in it, unchanged. A folder holding any other file (a user's notes, an edited
image, a folder mistyle did not make), and a folder that is or holds one of the run's inputs, is
refused whatever the options; so is a batch's ``--out`` holding anything but its outputs and
their ``index.html``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from .conventions import STYLE_SUFFIXES
from .files.paths import output_target
from .ownership import check_replaceable, is_beside_output, is_owned, read_manifest

REPORT_FILE = "report.json"
RENDER_KINDS = ("render", "sequence")
"""Manifest kinds of a render's folder: one run's (``staged_directory``), or chunks merged frame by frame."""
BATCH_KIND = "batch"


def is_mistyle_output(folder: Path) -> bool:
    """Whether ``folder`` is a complete render of mistyle's (its manifest is written last)."""
    record = read_manifest(folder)
    return record is not None and record.get("kind") in RENDER_KINDS


def check_not_an_input(folder: Path, inputs: list[Path]) -> None:
    """``ValueError`` when writing ``folder`` (which replaces it whole) would replace an input."""
    target = Path(folder).resolve()
    for path in inputs:
        resolved = Path(path).resolve()
        if resolved == target or target in resolved.parents:
            raise ValueError(
                f"The output folder {folder} is or holds the input {path}; writing it would replace that input. "
                "Choose an --out outside the inputs."
            )


def safe_name(text: str) -> str:
    """``text`` with anything but letters, digits, ``.``, ``_`` and ``-`` replaced by ``-`` (a folder name)."""
    return re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-.") or "unnamed"


@dataclass(frozen=True)
class StyleChoice:
    """One style of the run: an image, or a mix ``parts = ((image, weight), ...)`` (weights sum 1)."""

    name: str
    parts: tuple[tuple[Path, float], ...]

    @property
    def is_mix(self) -> bool:
        return len(self.parts) > 1

    def describe(self, names_only: bool = False) -> str:
        """The image's path, or the mix's weights and paths; ``names_only``: file names without their
        folders (what a sheet shows beside the density's file name)."""
        shown = [(Path(path).name if names_only else str(path), weight) for path, weight in self.parts]
        if not self.is_mix:
            return shown[0][0]
        return " + ".join(f"{weight:.2f} x {path}" for path, weight in shown)


@dataclass(frozen=True)
class DensitySource:
    """A density file or folder of frames (``mesh=False``), or a mesh to voxelize."""

    path: Path
    mesh: bool = False

    @property
    def name(self) -> str:
        return safe_name(self.path.name if self.path.is_dir() else self.path.stem)


@dataclass(frozen=True)
class Output:
    density: DensitySource
    style: StyleChoice
    folder: Path

    @property
    def name(self) -> str:
        return f"{self.density.name}__{self.style.name}"


def style_files(path: Path) -> list[Path]:
    """A style image, or the images in a folder (sorted); ``ValueError`` for a folder without any."""
    path = Path(path)
    if not path.is_dir():
        return [path]  # load_style reports a missing or unreadable file
    images = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in STYLE_SUFFIXES)
    if not images:
        raise ValueError(
            f"The style folder {path} holds no images ({', '.join(STYLE_SUFFIXES)}); "
            "give image files or a folder of them."
        )
    return images


def parse_mix_item(text: str) -> tuple[Path, float]:
    """``"image.png:0.7"`` -> ``(Path("image.png"), 0.7)``; ``ValueError`` naming the expected form."""
    path, _, weight = str(text).rpartition(":")
    try:
        value = float(weight)
    except ValueError:
        value = None
    if not path or value is None or not (value >= 0 and value < float("inf")):
        raise ValueError(
            f"--mix takes IMAGE:WEIGHT items with finite weights >= 0, e.g. --mix a.png:0.7 b.png:0.3; got {text!r}."
        )
    return Path(path), value


def style_choices(styles: list[Path] | None, mix: list[str] | None) -> list[StyleChoice]:
    """The run's styles: one per ``--style`` image (folders expanded), or the one ``--mix``."""
    if mix:
        parts = [parse_mix_item(item) for item in mix]
        if len(parts) < 2:
            raise ValueError("--mix needs two or more IMAGE:WEIGHT items; for one style use --style.")
        largest = max(weight for _, weight in parts)
        if largest <= 0:
            raise ValueError("--mix weights must not all be zero.")
        parts = [(path, weight / largest) for path, weight in parts]  # no overflow: 1e308 + 1e308 is inf
        total = sum(weight for _, weight in parts)
        parts = [(path, weight / total) for path, weight in parts]
        name = "mix-" + "-".join(f"{safe_name(path.stem)}{round(100 * weight)}" for path, weight in parts)
        return [StyleChoice(name, tuple(parts))]
    files = [image for style in styles for image in style_files(style)]
    return [StyleChoice(safe_name(image.stem), ((image, 1.0),)) for image in files]


def plan_outputs(
    densities: list[Path] | None,
    meshes: list[Path] | None,
    styles: list[Path] | None,
    mix: list[str] | None,
    out: Path,
    overwrite: bool,
    resume: bool = False,
) -> list[Output]:
    """Every (density, style) pair's output folder, checked before any work: distinct names, and no
    existing output replaced without ``overwrite`` or kept without ``resume`` (the caller then skips
    the complete ones: ``is_mistyle_output``). ``out`` a symbolic link: its target (``output_target``)."""
    out = output_target(out)
    sources = [DensitySource(Path(p)) for p in densities or []] + [
        DensitySource(Path(p), mesh=True) for p in meshes or []
    ]
    choices = style_choices(styles, mix)
    pairs = [(source, choice) for source in sources for choice in choices]
    single = len(pairs) == 1
    outputs = [
        Output(source, choice, Path(out) if single else Path(out) / f"{source.name}__{choice.name}")
        for source, choice in pairs
    ]
    seen: dict[str, Output] = {}
    for output in outputs:
        if output.name in seen:
            first = seen[output.name]
            raise ValueError(
                f"Two inputs would share the output {output.name}: {first.density.path} with "
                f"{first.style.describe()} and {output.density.path} with {output.style.describe()}; "
                "rename one of the files."
            )
        seen[output.name] = output
    inputs = [source.path for source in sources] + [image for choice in choices for image, _ in choice.parts]
    if not single:
        check_batch_root(Path(out), [output.folder.name for output in outputs])
    for output in outputs:
        folder = output.folder
        check_not_an_input(folder, inputs)
        if not folder.is_dir() or not any(folder.iterdir()):
            continue
        if resume and is_mistyle_output(folder):
            continue  # kept as it is; the caller checks it was made with this run's settings
        check_replaceable(folder)
        if not is_mistyle_output(folder):  # only the pending files of a killed merge: empty for our purposes
            continue
        if not overwrite and not resume:
            raise ValueError(
                f"{folder} already holds a render; pass --overwrite to replace it, --resume to keep it "
                "and make only the missing outputs, or choose another --out."
            )
    return outputs


def check_batch_root(out: Path, names: list[str]) -> None:
    """``ValueError`` when a batch's ``out`` holds anything but mistyle's: the outputs it plans
    (``names``, each checked on its own), complete renders of earlier batches, its ``index.html``
    (listed in the root's manifest) and the locks and staging folders beside them."""
    if out.exists() and not out.is_dir():
        raise ValueError(f"The output path {out} is a file; choose a folder for --out.")
    if out.is_dir():
        check_replaceable(out, also_ours=batch_entries(out, names))


def batch_entries(out: Path, names: list[str] = ()):
    """Whether a path in a batch's ``out`` (relative) is one of its outputs' (``names``, and the complete
    renders there) or their locks and staging folders; the root's own files are in its manifest."""
    renders = {p.name for p in out.iterdir() if p.is_dir() and not p.is_symlink() and is_owned(p)}
    allowed = set(names) | renders

    def ours(name: str) -> bool:
        return name.split("/")[0] in allowed or is_beside_output(name)

    return ours


def batch_renders(out: Path) -> list[Path]:
    """The complete outputs in a batch folder ``out``: what its index shows."""
    out = Path(out)
    if not out.is_dir():
        return []
    return sorted(p for p in out.iterdir() if p.is_dir() and not p.name.startswith(".") and is_mistyle_output(p))
