"""The benchmark's splits: which (density, style) pairs each one scores.

Densities and styles come from ``mistyle.data.heldout``, the one record of what training never sees
(styles kept apart by source, densities made from seeds no training set uses). ``quick`` is a small
slice of the same split, for a minute's check that everything runs (``mistyle-bench --quick``).
``validation`` is drawn like ``heldout`` from other pictures and seeds: recipes and experiments
choose checkpoints and arms on it, so that the held-out split only ever reports.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..data.heldout import (
    HELD_OUT_DENSITIES,
    HELD_OUT_SEED_BASE,
    HELD_OUT_STYLE_DIR,
    VALIDATION_DENSITIES,
    VALIDATION_STYLE_DIR,
    HeldOutDensity,
    held_out_styles,
)

QUICK_DENSITY = HeldOutDensity("pyroclastic32", "pyroclastic", 32, HELD_OUT_SEED_BASE + 3)
"""The held-out pyroclastic cloud's generator and seed at 32^3: the quick split's density."""


@dataclass(frozen=True)
class Split:
    name: str
    densities: tuple  # HeldOutDensity each
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
    names_in_split = list(chosen.styles) if chosen.styles is not None else known_styles
    by_name = {spec.name: spec for spec in chosen.densities}
    for names, known, what in ((densities, by_name, "density"), (styles, names_in_split, "style")):
        unknown = sorted(set(names or ()) - set(known))
        if unknown:
            raise ValueError(f"Split {split!r} has no {what} {', '.join(unknown)}; it has {', '.join(known)}.")
    specs = [by_name[name] for name in densities] if densities else list(chosen.densities)
    names = [name for name in names_in_split if not styles or name in styles]
    return [(spec, name) for spec in specs for name in names]
