"""The benchmark's splits: which (density, style) pairs each one scores.

Densities and styles come from ``mistyle.data.heldout``, the one record of what training never sees
(styles kept apart by source, densities made from seeds no training set uses). ``quick`` is a small
slice of the same split, for a minute's check that everything runs (``mistyle-bench --quick``).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..data.heldout import HELD_OUT_DENSITIES, HELD_OUT_SEED_BASE, HeldOutDensity, held_out_styles

QUICK_DENSITY = HeldOutDensity("pyroclastic32", "pyroclastic", 32, HELD_OUT_SEED_BASE + 3)
"""The held-out pyroclastic cloud's generator and seed at 32^3: the quick split's density."""


@dataclass(frozen=True)
class Split:
    name: str
    densities: tuple  # HeldOutDensity each
    styles: tuple | None  # held-out style names; None: all of them
    description: str


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
    )
}


def split_pairs(split: str, densities: list[str] | None = None, styles: list[str] | None = None) -> list[tuple]:
    """``(HeldOutDensity, style name)`` pairs of ``split``, optionally narrowed to the named densities
    and styles; ``ValueError`` naming an unknown split, density or style."""
    if split not in SPLITS:
        raise ValueError(f"Unknown split {split!r}; choose one of {', '.join(SPLITS)}.")
    chosen = SPLITS[split]
    known_styles = list(held_out_styles())
    split_styles = list(chosen.styles) if chosen.styles is not None else known_styles
    by_name = {spec.name: spec for spec in chosen.densities}
    for names, known, what in ((densities, by_name, "density"), (styles, split_styles, "style")):
        unknown = sorted(set(names or ()) - set(known))
        if unknown:
            raise ValueError(f"Split {split!r} has no {what} {', '.join(unknown)}; it has {', '.join(known)}.")
    specs = [by_name[name] for name in densities] if densities else list(chosen.densities)
    names = [name for name in split_styles if not styles or name in styles]
    return [(spec, name) for spec in specs for name in names]
