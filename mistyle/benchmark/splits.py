"""The benchmark's splits: which (density, style) pairs each one scores.

Densities and styles come from ``mistyle.data.heldout``, the one record of what training never sees
(styles kept apart by source, densities made from seeds no training set uses). ``quick`` is a small
slice of the same split, for a minute's check that everything runs (``mistyle-bench --quick``).
``validation`` is drawn like ``heldout`` from other pictures and seeds: recipes and experiments
choose checkpoints and arms on it, so that the held-out split only ever reports.

``real`` scores densities that other people made -- a production cloud and simulated smoke from
public repositories (``RealDensity``, stored under ``real/`` with each file's source,
commit, licence and author in ``real/SOURCES.toml``; ``scripts/make_real_split.py`` rebuilds them from
those sources) -- with ``REAL_STYLES``, seven of the held-out styles. Its densities are files, not
generators: load any split's density with ``split_density``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomllib

from ..data.heldout import (
    HELD_OUT_DENSITIES,
    HELD_OUT_SEED_BASE,
    HELD_OUT_STYLE_DIR,
    VALIDATION_DENSITIES,
    VALIDATION_STYLE_DIR,
    HeldOutDensity,
    held_out_density,
    held_out_styles,
)

QUICK_DENSITY = HeldOutDensity("pyroclastic32", "pyroclastic", 32, HELD_OUT_SEED_BASE + 3)
"""The held-out pyroclastic cloud's generator and seed at 32^3: the quick split's density."""

REAL_DIR = Path(__file__).resolve().parent / "real"
"""The real split's densities (``<name>.npz``, key ``density``) and their record ``SOURCES.toml``:
package data, so an installed mistyle benchmarks them without the repository."""

REAL_STYLES = (
    "hokusai_great_wave",
    "van_gogh_starry_night",
    "kandinsky_composition_vii",
    "munch_the_scream",
    "signac_la_calanque",
    "photo_nasa_carina_pillar",
    "texture_rusty_metal",
)
"""The held-out styles the real split pairs every real density with: five paintings (the Great Wave,
whose blues the issue's production cloud lost, among them), a photograph and a material texture."""


@dataclass(frozen=True)
class RealDensity:
    """A density made outside mistyle, stored as ``REAL_DIR/<file>``: ``kind`` is ``dense`` (a thick
    cloud, an opaque core) or ``thin`` (smoke); ``shape`` is the stored ``(Z, Y, X)``, at most 128 a
    side, values in [0, 1] (``SOURCES.toml`` says how each was cropped, resampled and normalised)."""

    name: str
    file: str
    kind: str
    shape: tuple
    description: str
    source: str  # "<repo>@<commit>:<path>"
    licence: str

    def describe(self) -> str:
        return f"{self.kind} real density {'x'.join(map(str, self.shape))} (Z, Y, X): {self.description}"

    def path(self, root: Path = REAL_DIR) -> Path:
        return Path(root) / self.file

    def load(self, root: Path = REAL_DIR) -> np.ndarray:
        """The density ``(Z, Y, X)`` float32, checked (``mistyle.files.load_density``)."""
        from ..files import load_density

        return load_density(self.path(root))


def real_densities(root: Path = REAL_DIR) -> tuple:
    """The ``RealDensity`` of every volume in ``root/SOURCES.toml``, in its order; ``()`` when the record
    is missing (``split_pairs("real")`` then says so)."""
    sources = Path(root) / "SOURCES.toml"
    if not sources.exists():
        return ()
    return tuple(
        RealDensity(
            name,
            record["file"],
            record["kind"],
            tuple(record["stored"]["shape_zyx"]),
            record["description"],
            f"{record['repo']}@{record['commit']}:{record['path']}",
            record["licence"],
        )
        for name, record in tomllib.loads(sources.read_text()).items()
    )


def split_density(spec, cache: Path | None = None) -> np.ndarray:
    """The density ``(Z, Y, X)`` float32 of any split's density spec: a ``RealDensity``'s file, or a
    generated one (``held_out_density``, cached under ``cache`` when given)."""
    if isinstance(spec, RealDensity):
        return spec.load()
    return held_out_density(spec, cache)


@dataclass(frozen=True)
class Split:
    name: str
    densities: tuple  # HeldOutDensity or RealDensity each (split_density loads either)
    styles: tuple | None  # names of the split's style set; None: all of them
    description: str
    style_dir: Path = HELD_OUT_STYLE_DIR  # the style set (a folder with SOURCES.toml)


SPLITS = {
    split.name: split
    for split in (
        Split(
            "heldout",
            tuple(d for d in HELD_OUT_DENSITIES if d.name in ("smoke64", "pyroclastic64")),
            None,
            "the held-out 64^3 densities (smoke, pyroclastic cloud) with every held-out style",
        ),
        Split(
            "heldout128",
            tuple(d for d in HELD_OUT_DENSITIES if d.name == "smoke128"),
            None,
            "the held-out 128^3 smoke with every held-out style",
        ),
        Split(
            "quick",
            (QUICK_DENSITY,),
            ("hokusai_great_wave", "signac_la_calanque"),
            "one 32^3 held-out cloud and two held-out styles: a minute's check that everything runs",
        ),
        Split(
            "validation",
            VALIDATION_DENSITIES,
            None,
            "for choosing checkpoints and arms: a smoke and a pyroclastic cloud from other seeds with the "
            "validation styles (other paintings, photographs and textures)",
            VALIDATION_STYLE_DIR,
        ),
        Split(
            "real",
            real_densities(),
            REAL_STYLES,
            "clouds and smoke that other people made (a production cloud, simulated smoke plumes and a puff; "
            "dense and thin; mistyle/benchmark/real/SOURCES.toml) with seven held-out styles, every pair",
        ),
    )
}


def split_styles(split: str) -> dict[str, dict]:
    """``name -> record`` (with its ``path``) of the style set ``split`` draws from."""
    if split not in SPLITS:
        raise ValueError(f"Unknown split {split!r}; choose one of {', '.join(SPLITS)}.")
    return held_out_styles(SPLITS[split].style_dir)


def split_pairs(split: str, densities: list[str] | None = None, styles: list[str] | None = None) -> list[tuple]:
    """``(HeldOutDensity, style name)`` pairs of ``split``, optionally narrowed to the named densities
    and styles; ``ValueError`` naming an unknown split, density or style."""
    known_styles = list(split_styles(split))
    chosen = SPLITS[split]
    if not chosen.densities:
        raise ValueError(f"Split {split!r} has no densities: {REAL_DIR / 'SOURCES.toml'} is missing.")
    names_in_split = list(chosen.styles) if chosen.styles is not None else known_styles
    by_name = {spec.name: spec for spec in chosen.densities}
    for names, known, what in ((densities, by_name, "density"), (styles, names_in_split, "style")):
        unknown = sorted(set(names or ()) - set(known))
        if unknown:
            raise ValueError(f"Split {split!r} has no {what} {', '.join(unknown)}; it has {', '.join(known)}.")
    specs = [by_name[name] for name in densities] if densities else list(chosen.densities)
    names = [name for name in names_in_split if not styles or name in styles]
    return [(spec, name) for spec in specs for name in names]
