"""README's Blender picture: mistyle's output opened in Blender 5.3 with README's recipe and rendered by
Cycles, beside mistyle's own path-traced render from the same camera (``results/blender/``).

    make setup && bash scripts/setup_blender.sh
    python experiments/blender_render.py [--style PATH] [--res 320]

It runs ``mistyle-render`` (this environment) and ``tests/blender/blender_side.py recipe`` under
``.venv-blender``'s Python, as ``make test-blender`` does.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--style", type=Path, default=ROOT / "mistyle/data/heldout_styles/van_gogh_starry_night.jpg")
    parser.add_argument("--density", type=Path, default=ROOT / "examples/smoke_64.vol")
    parser.add_argument("--res", type=int, default=320)
    parser.add_argument("--spp", type=int, default=128)
    parser.add_argument("--blender-python", type=Path, default=ROOT / ".venv-blender/bin/python")
    parser.add_argument("--out", type=Path, default=ROOT / "results/blender")
    args = parser.parse_args()

    import numpy as np
    from PIL import Image

    from mistyle.conventions import DEFAULT_ENV_RADIANCE
    from mistyle.files.vdb import vdb_info

    args.out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="mistyle-blender-")) / "out"
    subprocess.run(
        [sys.executable, "-m", "mistyle.render_final", "--density", str(args.density), "--style", str(args.style),
         "--vdb", "--up", "z", "--res", str(args.res), "--spp", str(args.spp), "--out", str(work), "--overwrite",
         "--quiet"],
        check=True,
    )  # fmt: skip
    metadata = vdb_info(work / "volume.vdb")["file_metadata"]
    job = {
        "vdb": str(work / "volume.vdb"),
        "world_density_scale": metadata["mistyle_world_density_scale"],
        "scene_xml": str(work / "scene.xml"),
        "radiance": DEFAULT_ENV_RADIANCE,
        "res": args.res,
        "spp": args.spp,
        "image": str(work / "blender_cycles.png"),
        "result": str(args.out / "blender_result.json"),
    }
    (args.out / "blender_job.json").write_text(json.dumps(job))
    subprocess.run(
        [
            str(args.blender_python),
            str(ROOT / "tests/blender/blender_side.py"),
            "recipe",
            str(args.out / "blender_job.json"),
        ],
        check=True,
        capture_output=True,
    )
    blender = Image.open(work / "blender_cycles.png").convert("RGBA")
    shown = Image.new("RGBA", blender.size, (0, 0, 0, 255))
    shown.alpha_composite(blender)
    ours = Image.open(work / "final.png").convert("RGB").resize(blender.size)
    style = Image.open(args.style).convert("RGB")
    style = style.resize((round(style.width * blender.height / style.height), blender.height))
    sheet = np.concatenate([np.asarray(style), np.asarray(ours), np.asarray(shown.convert("RGB"))], axis=1)
    Image.fromarray(sheet).convert("RGB").save(args.out / "side_by_side.jpg", quality=88)
    for name in ("blender_job.json", "blender_result.json"):
        (args.out / name).unlink()
    shutil.rmtree(work.parent)
    print(args.out / "side_by_side.jpg")


if __name__ == "__main__":
    main()
