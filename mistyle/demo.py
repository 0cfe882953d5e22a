"""``python -m mistyle.demo`` (``make demo``): the main job on bundled data.

Stylizes the bundled cloud ``examples/pyroclastic_64.vol`` in the look of Hokusai's *Great Wave*
(``mistyle/data/heldout_styles/hokusai_great_wave.jpg``, a style the network never trained on) with the
bundled network as ``mistyle-render`` does by default (a look fitted on the frame and applied,
``Pipeline.fits_look``), path-traces a turntable of 256^2 images with Mitsuba's ``volpath`` (multiple
scattering, the training light), and writes the albedo grid, EXR/PNG frames, an MP4 and a GIF,
``sheet.png`` (style | network | default output), ``scene.xml`` and ``report.json`` to ``out/demo``
(replacing an earlier demo). Any option of ``python -m mistyle.render_final`` can be appended, e.g.
``python -m mistyle.demo --style my.png --coat dielectric:1.5``.

The pair is chosen so that the picture shows what mistyle does: a dense cloud shows the albedo of its
visible skin, where a thin smoke sums it over its whole depth, and the wave's blues and cream are far
from the network's own colours (``docs/decisions/2026-12-05-solid-texture.md``: the marble on the thin
smoke, the demo before, renders as a pale blob whatever albedo it is given).
"""

from __future__ import annotations

import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
EXAMPLES = PACKAGE.parent / "examples"
DEFAULTS = {
    "--density": str(EXAMPLES / "pyroclastic_64.vol"),
    "--style": str(PACKAGE / "data" / "heldout_styles" / "hokusai_great_wave.jpg"),
    "--out": "out/demo",
    "--turntable": "8",
    "--res": "256",  # large enough to see the strokes on the sheet
    "--spp": "32",
}


def main(argv=None) -> int:
    from .render_final import main as render_final

    argv = list(sys.argv[1:] if argv is None else argv)
    given = {arg.split("=")[0] for arg in argv if arg.startswith("--")}
    if "--mesh" in given:
        given.add("--density")
    defaults = [item for key, value in DEFAULTS.items() if key not in given for item in (key, value)]
    return render_final(defaults + ["--overwrite"] + argv)  # the demo is made to be run again


if __name__ == "__main__":
    sys.exit(main())
