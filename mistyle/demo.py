"""``python -m mistyle.demo`` (``make demo``): the main job on bundled data.

Stylizes the bundled smoke frame ``examples/smoke_64.vol`` with the bundled style
``examples/style_marble.png`` with the bundled network as ``mistyle-render`` does by default (a look
fitted on the frame and applied, ``Pipeline.fits_look``), path-traces a small turntable
with Mitsuba's ``volpath`` (multiple scattering, the training light), and writes the albedo grid, EXR/PNG
frames, an MP4 and a GIF, ``sheet.png``, ``scene.xml`` and ``report.json`` to ``out/demo`` (replacing an
earlier demo). Any option of ``python -m mistyle.render_final`` can be appended, e.g.
``python -m mistyle.demo --style my.png --coat dielectric:1.5``.
"""

from __future__ import annotations

import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
DEFAULTS = {
    "--density": str(EXAMPLES / "smoke_64.vol"),
    "--style": str(EXAMPLES / "style_marble.png"),
    "--out": "out/demo",
    "--turntable": "8",
    "--res": "128",
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
