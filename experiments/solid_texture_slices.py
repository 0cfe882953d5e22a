"""Stage (b) of #48's study: does a solid texture's every slice look like the style, before any render?

For a few held-out and validation styles: the structure distance (``objective.structure``) of 15 axis
slices of ``synthesise_solid_texture``'s texture (5 along each axis) against the style at the finest
exemplar size, with the default settings and with ``LONGER`` (4x the steps and patches, 2x the
projections: how much the defaults give up for their speed), next to the same slices of ``tuned_noise``
(the strongest training-free field); seconds of each synthesis; a strip of slices per style.

    .venv/bin/python experiments/solid_texture_slices.py    # about 3 min on 2 cores
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

OUT = ROOT / "results" / "solid_texture_study"
LONGER = dict(steps=120, patches=16384, projections=128, pool=512)
STYLES = (
    "heldout_styles/hokusai_great_wave.jpg",
    "heldout_styles/van_gogh_starry_night.jpg",
    "validation_styles/klimt_the_kiss.jpg",
    "validation_styles/photo_nasa_io_global.jpg",
)


def slices(texture: np.ndarray) -> list[np.ndarray]:
    places = range(4, texture.shape[0], max(1, texture.shape[0] // 5))
    return [texture[i] for i in places] + [texture[:, i] for i in places] + [texture[:, :, i] for i in places]


def main() -> None:
    from PIL import Image

    from mistyle.benchmark.methods import tuned_noise
    from mistyle.files import load_style
    from mistyle.objective.structure import structure_distance
    from mistyle.solid_texture import SolidTextureSettings, exemplar_pyramid, synthesise_solid_texture

    settings = SolidTextureSettings()
    noise = tuned_noise((settings.side,) * 3)
    record, strips = {}, []
    for relative in STYLES:
        style = load_style(ROOT / "mistyle" / "data" / relative)
        exemplar = exemplar_pyramid(style, settings)[-1][0].permute(1, 2, 0).numpy()
        started = time.perf_counter()
        texture = synthesise_solid_texture(style, settings)
        seconds = time.perf_counter() - started
        started = time.perf_counter()
        longer = synthesise_solid_texture(style, SolidTextureSettings(**LONGER))
        longer_seconds = time.perf_counter() - started
        name = Path(relative).stem
        record[name] = {
            "solid_texture": {"structure": structure_distance(slices(texture), None, exemplar), "seconds": seconds},
            "solid_texture_longer": {
                "structure": structure_distance(slices(longer), None, exemplar),
                "seconds": longer_seconds,
            },
            "tuned_noise": {"structure": structure_distance(slices(noise), None, exemplar)},
        }
        print(name, record[name], flush=True)
        side = 160
        shown = [Image.fromarray((exemplar * 255).astype(np.uint8)).resize((side, side))]
        shown += [Image.fromarray((s * 255).astype(np.uint8)).resize((side, side)) for s in slices(texture)[::3]]
        strips.append(np.concatenate([np.asarray(image) for image in shown], axis=1))
    OUT.mkdir(parents=True, exist_ok=True)
    record["machine"] = f"{platform.machine()}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.2f} at the end"
    (OUT / "slices.json").write_text(json.dumps(record, indent=2) + "\n")
    Image.fromarray(np.concatenate(strips)).save(OUT / "slices.jpg", quality=90)


if __name__ == "__main__":
    main()
