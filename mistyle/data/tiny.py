"""A tiny fixed dataset for tests and CI: small smoke frames with velocity and Ls, and a few styles.

Made in a few seconds from fixed seeds, with the same generators as the full datasets::

    tiny/smoke/manifest.json, tiny/smoke/plume000P/frame000F.npz   (2 plumes, 4 frames, 16^3)
    tiny/styles/*.png                                             (6 styles, 32^2)
"""

from __future__ import annotations

from pathlib import Path

from ..files import write_png
from .generate import SmokeDatasetSpec, generate_smoke
from .styles import offline_style_set

TINY_SMOKE = SmokeDatasetSpec(resolution=16, plumes=2, frames=16, keep_first=13, keep_last=16, seed=7, directions=32)


def make_tiny_dataset(out, log=print) -> Path:
    """Write (or complete) the tiny dataset under ``out``; returns ``out``."""
    out = Path(out)
    generate_smoke(TINY_SMOKE, out / "smoke", log=log)
    styles = offline_style_set(
        size=32, crops_per_photo=1, palettes_per_texture=1, materials_each=1, crops_per_painting=0, seed=7
    )
    for name, image in styles[::3]:
        path = out / "styles" / (name.replace("/", "_") + ".png")
        if not path.is_file():
            write_png(path, image, srgb=False)
    return out
