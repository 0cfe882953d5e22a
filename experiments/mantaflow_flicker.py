"""Does a real simulation whose box grows stylize coherently with its own velocities? (#49 part 2-3)

Blender's own Mantaflow cache, ten frames of the ``c42`` smoke by markste-in (the frames
``tests/data/mantaflow`` cuts down; source, commit and hashes below): 24 grids a file, the density's
active box growing from 11x9x28 voxels to 51x71x29, a staggered ``velocity`` grid in every frame.
``load_density_frames`` places the frames in one index box (their union) and reads the velocities in
the solver's units (``--up z``, as Blender writes them). The default output stylizes the sequence: one
look fitted on its first, middle and last frame and applied to every frame (``Pipeline.stylize``).

Measured on the albedo (inside the medium of both frames of each step, so the box's empty margins count
for nothing): the flicker with the file's velocities (each frame against the previous one warped by its
velocity, ``objective.metrics.temporal_flicker``'s warp), the flicker without warping (the frames as
they are), for the look's albedo and the feed-forward network's. #49 asks that the first be at most the
second. The velocities' units are checked on the density itself (warped by them at 0.25x to 2x, the
frames differ least at the scale that is right). Also each frame path traced at 128^2 (64 spp, denoised,
one view) for the strip in ``strip.jpg``.

    .venv/bin/python experiments/mantaflow_flicker.py --cache data/mantaflow_c42     # about 3 min

``--cache``: a folder holding ``fluid_data_0001.vdb`` ... ``fluid_data_0010.vdb`` of
https://github.com/markste-in/c42 at 6c87b04a9c2738e33c1167801e9d9c164e7b0035 (``cache/data/``; WTFPL-2.0),
checked against ``SHA256`` below.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

OUT = ROOT / "results" / "mantaflow_flicker"
STYLE = ROOT / "mistyle" / "data" / "heldout_styles" / "hokusai_great_wave.jpg"
SHA256 = {
    "fluid_data_0001.vdb": "323b31cbbb5af6adc2398f36b9cc3f664f8b4bad332a41f0258313888654cc97",
    "fluid_data_0010.vdb": "dea5d04fcd8bf378a161777e11af275bb43d15853c14f41b64eb4f324f08237e",
}


def flicker(albedos: np.ndarray, densities: np.ndarray, velocities: np.ndarray | None) -> dict:
    """Two measures of ``|A_t - W(A_{t-1})|``, ``W`` the warp by frame t-1's velocity (None: no warp):
    ``"inside"``, its mean over the voxels with medium in both frames at the same place (the measure of
    stop 59); ``"medium"``, its mean weighted by ``min(ρ_t, W(ρ_{t-1}))``, the medium both frames have
    where the comparison reads them. The second is what renders: a voxel counts as much as the matter
    it holds, and a warped comparison that reads the previous frame outside its medium (where the albedo
    is the network's value for no density, never seen) counts for nothing."""
    import torch

    from mistyle.warp import semi_lagrangian_warp

    previous, before = albedos[:-1], densities[:-1]
    if velocities is not None:
        volumes = torch.from_numpy(np.ascontiguousarray(previous)).permute(0, 4, 1, 2, 3)
        flow = torch.from_numpy(np.ascontiguousarray(velocities[:-1])).permute(0, 4, 1, 2, 3)
        previous = semi_lagrangian_warp(volumes, flow).permute(0, 2, 3, 4, 1).numpy()
        before = semi_lagrangian_warp(torch.from_numpy(np.ascontiguousarray(before))[:, None], flow)[:, 0].numpy()
    change = np.abs(albedos[1:] - previous).mean(axis=-1)
    inside = (densities[1:] > 0) & (densities[:-1] > 0)
    weight = np.minimum(densities[1:], before)
    return {"inside": float(change[inside].mean()), "medium": float((change * weight).sum() / weight.sum())}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", type=Path, required=True, help="the folder of the ten fluid_data_*.vdb files")
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--res", type=int, default=128)
    args = parser.parse_args(argv)
    for name, digest in SHA256.items():
        if hashlib.sha256((args.cache / name).read_bytes()).hexdigest() != digest:
            raise SystemExit(f"{args.cache / name} is not the recorded file (sha256 {digest}).")

    from mistyle.advection import TextureMotion
    from mistyle.files import load_density_frames, write_jpeg
    from mistyle.objective.metrics import style_fidelity
    from mistyle.pipeline import Pipeline, PipelineSettings, RenderSettings
    from mistyle.tone import display

    notes: list[str] = []
    loaded = load_density_frames(args.cache, up="z", notes=notes)
    pipeline = Pipeline(PipelineSettings(render=RenderSettings(res=args.res, spp=64)))
    started = time.perf_counter()
    stylized = pipeline.stylize(loaded.densities, STYLE, velocities=loaded.velocities, notes=notes)
    seconds = time.perf_counter() - started
    densities, velocities = np.stack(loaded.densities), np.stack(loaded.velocities)
    look = stylized.look
    record = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
        "frames": len(loaded.densities),
        "shape_zyx": list(loaded.densities[0].shape),
        "occupied": [float((d > 0).mean()) for d in loaded.densities],
        "stylize_seconds": seconds,
        "key_frames": look.meta["key_frames"],
        "notes": notes,
    }
    # The velocities' units checked on the density itself, which the flow carries: warped by them the
    # frames should differ less than as they are, and most at the units read (scale 1).
    for scale in (0.25, 0.5, 1.0, 2.0):
        record[f"density_flicker_warped_x{scale:g}"] = flicker(densities[..., None], densities, velocities * scale)
    record["density_flicker_unwarped"] = flicker(densities[..., None], densities, None)
    # One look, its texture fixed in the box or advected with restarts every `period` frames.
    arms = {"network": stylized.network, "look_fixed": [look.apply(grid) for grid in loaded.densities]}
    for period in (4, 8, 16):
        motion = TextureMotion(list(loaded.velocities), period=period)
        arms[f"look_advected_{period}"] = [
            look.apply(grid, motion.phases(i)) for i, grid in enumerate(loaded.densities)
        ]
    assert all(np.array_equal(a, b) for a, b in zip(arms["look_advected_8"], stylized.albedos))
    for name, albedos in arms.items():
        stacked = np.stack(albedos)
        record[f"{name}_flicker_warped"] = flicker(stacked, densities, velocities)
        record[f"{name}_flicker_unwarped"] = flicker(stacked, densities, None)
    strips = []
    for name in ("look_fixed", "look_advected_8"):
        images, _ = pipeline.path_trace(stylized.frames, arms[name], pipeline.views()[:1])
        scores = [style_fidelity([image], look.style) for image in images]
        record[f"{name}_per_frame"] = scores
        strips.append(np.concatenate([display(image) for image in images], axis=1))
    args.out.mkdir(parents=True, exist_ok=True)
    write_jpeg(args.out / "strip.jpg", np.concatenate(strips, axis=0), srgb=False)
    (args.out / "flicker.json").write_text(json.dumps(record, indent=1) + "\n")
    print(json.dumps({key: value for key, value in record.items() if "flicker" in key}, indent=1))


if __name__ == "__main__":
    main()
