"""What one ``render_final`` run makes: an output per (density, style) pair, named after its inputs.

``--density``/``--mesh`` and ``--style`` take several values (or shell globs); a ``--style``
folder stands for the images in it, and a ``--density`` folder for one sequence of frames (as
before). ``--mix a.png:0.7 b.png:0.3`` is one style made of several. A single pair is written to
``--out`` itself; several go to ``--out/{density}__{style}/`` with an ``index.html`` beside them.
An output that already exists is refused unless ``--overwrite`` is given, before any work starts.

``--overwrite`` replaces only what mistyle wrote: a folder is a mistyle output when it holds the
``report.json`` every render writes (``is_mistyle_output``). A folder with other files, and a
folder that is or holds one of the run's inputs, is refused whatever the options.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

STYLE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp", ".exr")
REPORT_FILE = "report.json"
"""Written into every output (last, so only a complete output has it): what marks a folder as mistyle's."""


def is_mistyle_output(folder: Path) -> bool:
    """Whether ``folder`` holds a render's ``report.json`` (a JSON object with its ``inputs``)."""
    try:
        report = json.loads((Path(folder) / REPORT_FILE).read_text())
    except (OSError, ValueError):
        return False
    return isinstance(report, dict) and "inputs" in report


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

    def describe(self) -> str:
        if not self.is_mix:
            return str(self.parts[0][0])
        return " + ".join(f"{weight:.2f} x {path}" for path, weight in self.parts)


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
        total = sum(weight for _, weight in parts)
        if total <= 0:
            raise ValueError("--mix weights must not all be zero.")
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
    the complete ones: ``is_mistyle_output``)."""
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
    for output in outputs:
        folder = output.folder
        check_not_an_input(folder, inputs)
        if folder.is_dir() and any(p for p in folder.iterdir() if not p.name.startswith(".")):
            if not is_mistyle_output(folder):
                raise ValueError(
                    f"{folder} holds files that are not a mistyle render (it has no {REPORT_FILE} from "
                    "mistyle-render); --overwrite replaces only mistyle's own outputs. Choose another --out, "
                    "or empty that folder."
                )
            if not overwrite and not resume:
                raise ValueError(
                    f"{folder} already holds a render; pass --overwrite to replace it, --resume to keep it "
                    "and make only the missing outputs, or choose another --out."
                )
    return outputs


def batch_renders(out: Path) -> list[Path]:
    """The complete outputs in a batch folder ``out``: what its index shows."""
    out = Path(out)
    if not out.is_dir():
        return []
    return sorted(p for p in out.iterdir() if p.is_dir() and not p.name.startswith(".") and is_mistyle_output(p))
