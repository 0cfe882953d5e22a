"""``python -m mistyle.render_final``: stylize a density (or mesh, or sequence) and path-trace it.

    python -m mistyle.render_final --density examples/smoke_64.vol --style examples/style_marble.png --out out/marble
    python -m mistyle.render_final --density smoke.vol --style jade.png --coat dielectric:1.5 --turntable 24 --out out/jade
    python -m mistyle.render_final --mesh bunny.ply --style marble.png --coat dielectric --out out/bunny
    python -m mistyle.render_final --density data/fire/ --style lava.png --out out/fire     # a folder of frames

Writes into ``--out``: ``albedo.vol`` / ``albedo.npy`` (``albedo_frameNNNN.*`` for sequences), per
image ``*.exr`` (linear) and ``*.png`` (the training tone curve), ``turntable.mp4``/``.gif`` or
``sequence.mp4``/``.gif``, and ``report.json`` with timings and style metrics: ``swd_final`` (the
path-traced images against the style), ``swd_layer`` (the fast layer's image of the same views
under the training light), ``swd_plain`` (path traced without the correction) when a correction
or refinement is applied, and ``temporal_flicker`` for sequences. By default single frames are
refined for a few steps with the path tracer in the loop (``--refine``), which brought the final
renders closest to unseen styles; ``--refine 0`` renders the network's albedo as predicted.
Every file is written to a temporary name and renamed, so an interrupted run leaves no half-written output.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

DENSITY_SUFFIXES = (".vol", ".npy", ".npz")
# Measured on 3 unseen styles (experiments/final_appearance.py): SWD to the style 0.126 fast layer,
# 0.098 plain volpath, 0.105 calibrated, 0.080 after 16 refinement steps from the plain albedo
# (about 7 s per 64^3 frame on 2 cores). Sequences are not refined by default: refining frames
# independently against random views would bring back the flicker the network avoids.
DEFAULT_REFINE_STEPS = 16


def _coat(text: str) -> float:
    kind, _, ior = text.partition(":")
    if kind != "dielectric":
        raise argparse.ArgumentTypeError(f"--coat takes dielectric[:ior], e.g. dielectric:1.5; got {text!r}")
    try:
        return float(ior) if ior else 1.5
    except ValueError:
        raise argparse.ArgumentTypeError(f"--coat dielectric:<ior> needs a number, got {ior!r}") from None


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m mistyle.render_final", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--density", type=Path, help=".vol, .npy or .npz density, or a folder of frames")
    source.add_argument("--mesh", type=Path, help="closed .ply/.obj mesh, voxelized into a density")
    p.add_argument("--style", type=Path, required=True, help="style image (PNG/JPEG)")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--checkpoint", type=Path, default=None, help="SKPN checkpoint (default: the bundled one)")
    p.add_argument("--vgg-weights", default=None, help="VGG16 weights, for checkpoints trained with VGG16")
    p.add_argument("--view", type=float, default=0.0625, help="camera position on the training orbit, in [0, 1)")
    p.add_argument("--turntable", type=int, default=0, help="render N frames around the orbit (a video)")
    p.add_argument("--camera-distance", type=float, default=None, help="orbit radius (default: the checkpoint's)")
    p.add_argument("--light", default="constant", help="constant[:Le] | envmap:<file.exr>[:scale] | point:x,y,z[:I] | area[:L]")
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--max-depth", type=int, default=-1, help="-1: full multiple scattering; 2: single scattering")
    p.add_argument("--res", type=int, default=256)
    p.add_argument("--density-scale", type=float, default=None, help="extinction per unit density (default: training's)")
    p.add_argument("--coat", type=_coat, default=None, metavar="dielectric[:ior]", help="smooth dielectric boundary")
    p.add_argument("--scale-structures", type=float, default=1.0, help="resample the density by f before stylizing")
    p.add_argument("--mesh-res", type=int, default=64, help="voxels along the mesh's longest side")
    p.add_argument("--correct", choices=("calibrate", "none"), default="none",
                   help="calibrate: map the albedo so its multiply-scattered brightness matches single scattering")
    p.add_argument("--refine", type=int, default=None, metavar="STEPS",
                   help=f"refine the albedo for STEPS steps against the style with the path tracer in the loop "
                        f"(default: {DEFAULT_REFINE_STEPS} for a single frame, 0 for sequences)")
    p.add_argument("--fps", type=int, default=12)
    p.add_argument("--device", choices=("cpu", "cuda"), default="cpu")
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    try:
        return run(args)
    except (ValueError, OSError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except RuntimeError as error:
        from .backend import BackendError

        if isinstance(error, BackendError):
            print(f"error: {error}", file=sys.stderr)
            return 2
        raise


def load_frames(path: Path) -> tuple[list[np.ndarray], list[np.ndarray] | None, list[str]]:
    """Density frames from a file or a folder of frames: ``(densities, velocities or None, names)``."""
    from .data.generate import load_frame
    from .volume import load_density, validate_density

    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in DENSITY_SUFFIXES and p.is_file())
        if not files:
            raise ValueError(f"The folder {path} holds no .vol, .npy or .npz density frames.")
    elif path.is_file():
        files = [path]
    else:
        raise ValueError(f"Density {path} does not exist.")
    densities, velocities = [], []
    for file in files:
        if file.suffix.lower() == ".npz":
            try:
                frame = load_frame(file)
            except ValueError:  # a density-only npz (e.g. fire frames)
                with np.load(file, allow_pickle=False) as data:
                    if "density" not in data.files:
                        raise ValueError(f"{file} has no 'density' array.") from None
                    frame = {"density": data["density"], "velocity": data["velocity"] if "velocity" in data.files else None}
            densities.append(validate_density(frame["density"], name=str(file)))
            velocities.append(None if frame.get("velocity") is None else np.asarray(frame["velocity"], np.float32))
        else:
            densities.append(load_density(file))
            velocities.append(None)
    shapes = {d.shape for d in densities}
    if len(shapes) > 1:
        raise ValueError(f"The frames in {path} have different shapes {sorted(shapes)}; a sequence needs one grid size.")
    return densities, (velocities if all(v is not None for v in velocities) else None), [f.stem for f in files]


def run(args) -> int:
    from .api import Stylizer, display, load_style, path_trace
    from .backend import use_variant
    from .io import atomic_write_bytes, check_writable_dir, write_exr, write_png
    from .scenes import CameraPath, prepare_density
    from .scenes.final import LightSpec
    from .scenes.medium import validate_density_scale
    from .train.metrics import style_distance, temporal_flicker
    from .volume import write_vol

    # ---- every input checked before any heavy work
    if args.spp < 1 or not 8 <= args.res <= 8192 or args.turntable < 0 or args.fps < 1 or (args.refine or 0) < 0:
        raise ValueError("Need --spp >= 1, 8 <= --res <= 8192, --turntable >= 0, --fps >= 1 and --refine >= 0.")
    notes: list[str] = []
    style = load_style(args.style, notes)
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    check_writable_dir(args.out)
    use_variant(args.device)
    stylizer = Stylizer(args.checkpoint, args.device, args.vgg_weights)
    config = stylizer.config
    radiance = config.render.radiance
    light = LightSpec.parse(args.light, default_radiance=radiance)
    density_scale = validate_density_scale(args.density_scale if args.density_scale is not None else stylizer.density_scale)
    coat_mesh = None
    if args.mesh is not None:
        from .data.mesh import fit_to_box, load_mesh, voxelize, write_ply

        vertices, faces = load_mesh(args.mesh)
        densities, velocities, names = [voxelize(vertices, faces, args.mesh_res, supersample=2)], None, [args.mesh.stem]
        if args.coat is not None:
            placed, _ = fit_to_box(np.asarray(vertices, np.float64), args.mesh_res, 0.05)
            coat_mesh = write_ply(args.out / "coat_mesh.ply", placed, faces)
    else:
        densities, velocities, names = load_frames(args.density)
    for name, grid in zip(names, densities):
        if not grid.any():
            raise ValueError(f"The density {name} is all zero; there is no medium to stylize or render.")
    sequence = len(densities) > 1
    if args.refine is None:
        args.refine = 0 if sequence else DEFAULT_REFINE_STEPS
    distance = args.camera_distance or config.render.camera_distance
    orbit = CameraPath(distance=distance)
    views = orbit.turntable(args.turntable, offset=args.view) if args.turntable else [orbit.view(args.view)]
    report = {"inputs": {"density": str(args.density or args.mesh), "style": str(args.style), "frames": len(densities),
                         "shape_zyx": list(densities[0].shape), "checkpoint": str(stylizer.path), "light": args.light,
                         "spp": args.spp, "max_depth": args.max_depth, "res": args.res, "density_scale": density_scale,
                         "coat_ior": args.coat, "scale_structures": args.scale_structures, "correction": args.correct,
                         "refine_steps": args.refine, "views": len(views)}, "notes": notes}

    # ---- stylize
    started = time.perf_counter()
    albedos = [stylizer(grid, style, args.scale_structures) for grid in densities]
    report["stylize_seconds"] = time.perf_counter() - started
    print(f"stylized {len(albedos)} frame(s) of {densities[0].shape} in {report['stylize_seconds']:.2f} s", file=sys.stderr)
    for index, albedo in enumerate(albedos):
        stem = f"albedo_frame{index:04d}" if sequence else "albedo"
        write_vol(args.out / f"{stem}.vol", albedo)
        _write_npy(args.out / f"{stem}.npy", albedo)
    if sequence and velocities is not None:
        report["temporal_flicker"] = temporal_flicker(np.stack(albedos), np.stack(velocities))
    elif sequence:
        report["temporal_flicker_unwarped"] = float(np.mean(np.abs(np.diff(np.stack(albedos), axis=0))))
        report["notes"].append("the frames carry no velocity; temporal_flicker_unwarped compares frames without warping")

    # ---- correction for multiple scattering
    prepared = {}  # frame -> PreparedDensity (its Ls grid), computed once per frame

    def prepared_frame(frame):
        if frame not in prepared:
            prepared[frame] = prepare_density(densities[frame], density_scale)
        return prepared[frame]

    rendered_albedos = albedos
    if args.correct == "calibrate":
        from .correct import measure_calibration

        calibration = measure_calibration(densities[0], density_scale, radiance, views[:2], res=64, spp=16,
                                          prepared=prepared_frame(0))
        rendered_albedos = [calibration.apply(a) for a in albedos]
        report["calibration"] = calibration.as_dict()
        print(f"multiple-scattering calibration in {calibration.seconds:.1f} s", file=sys.stderr)
    if args.refine:
        from .correct import refine_albedo
        from .train.dataset import square_style
        from .train.objective import StyleObjective

        objective = StyleObjective(stylizer.extractor, config.loss.style, config.loss.rgb_weight)
        target = square_style(style, config.data.style_size).permute(1, 2, 0).numpy()
        refined, seconds = [], 0.0
        for index, (grid, albedo) in enumerate(zip(densities, rendered_albedos)):
            result, took = refine_albedo(grid, density_scale, albedo, target, objective, steps=args.refine, res=min(args.res, 64),
                                         radiance=radiance, camera_distance=distance, tv_weight=config.loss.tv_weight,
                                         progress=lambda done, count, loss: print(
                                             f"refining frame {index}: step {done}/{count}, loss {loss:.4g}", file=sys.stderr))
            refined.append(result)
            seconds += took
        rendered_albedos = refined
        report["refine_seconds"] = seconds
        for index, albedo in enumerate(refined):
            stem = f"albedo_refined_frame{index:04d}" if sequence else "albedo_refined"
            write_vol(args.out / f"{stem}.vol", albedo)

    # ---- path trace: a turntable of one frame, or every frame of a sequence from the views in turn
    render_seconds, images, layer_images = [], [], []
    jobs = [(i, [views[i % len(views)]]) for i in range(len(densities))] if sequence else [(0, views)]
    total = sum(len(v) for _, v in jobs)

    finished = []

    def progress(done, count, seconds):
        finished.append(seconds)
        print(f"path tracing {len(finished)}/{total}: {seconds:.1f} s", file=sys.stderr, flush=True)

    started = time.perf_counter()
    for frame, frame_views in jobs:
        frame_images, seconds = path_trace(densities[frame], rendered_albedos[frame], frame_views, args.res, args.spp,
                                           args.max_depth, density_scale, light, args.coat, coat_mesh, args.device,
                                           progress=progress)
        images += frame_images
        render_seconds += seconds
        layer_images += _layer_images(prepared_frame(frame), albedos[frame], frame_views, args.res, config, args.device)
    report["render_seconds"] = time.perf_counter() - started
    report["render_seconds_per_image"] = float(np.mean(render_seconds))

    kind = "sequence" if sequence else "turntable" if args.turntable else "view"
    for index, image in enumerate(images):
        stem = f"{kind}_{index:04d}" if len(images) > 1 else "final"
        write_exr(args.out / f"{stem}.exr", image)
        write_png(args.out / f"{stem}.png", display(image), srgb=False)
        write_png(args.out / f"{stem}_layer.png", display(layer_images[index]), srgb=False)
    if len(images) > 1:
        frames = [(display(image) * 255 + 0.5).astype(np.uint8) for image in images]
        report["video"] = [str(write_mp4(args.out / f"{kind}.mp4", frames, args.fps)), str(write_gif(args.out / f"{kind}.gif", frames, args.fps))]

    # ---- style metrics
    final = [style_distance(image, style) for image in images]
    report["swd_final"] = float(np.mean([distance["swd"] for distance in final]))
    report["hist_final"] = float(np.mean([distance["hist"] for distance in final]))
    report["swd_layer"] = float(np.mean([style_distance(image, style)["swd"] for image in layer_images]))
    if args.correct != "none" or args.refine:
        # The same views and settings without the correction: how much the correction moved the metric.
        plain = [image for frame, frame_views in jobs
                 for image in path_trace(densities[frame], albedos[frame], frame_views, args.res, args.spp, args.max_depth,
                                         density_scale, light, args.coat, coat_mesh, args.device)[0]]
        report["swd_plain"] = float(np.mean([style_distance(image, style)["swd"] for image in plain]))
    atomic_write_bytes(args.out / "report.json", (json.dumps(report, indent=1) + "\n").encode())
    print(json.dumps({k: report[k] for k in ("stylize_seconds", "render_seconds", "swd_layer", "swd_final") if k in report}))
    print(f"wrote {args.out}/: albedo grid(s), {len(images)} image(s) (EXR + PNG)"
          + (", MP4 and GIF" if len(images) > 1 else "") + ", report.json")
    return 0


def _layer_images(prepared, albedo, views, res, config, device="cpu") -> list[np.ndarray]:
    import torch

    from .bridge_torch import render_views

    with torch.no_grad():
        images = render_views(torch.from_numpy(albedo).permute(3, 0, 1, 2).to(device), prepared, views, res,
                              steps=config.render.steps, radiance=config.render.radiance)
    return [image.permute(1, 2, 0).cpu().numpy() for image in images]


def _write_npy(path: Path, array: np.ndarray) -> Path:
    from .io import atomic_output

    with atomic_output(path) as tmp:
        with open(tmp, "wb") as handle:
            np.save(handle, array)
    return path


def write_mp4(path: Path, frames: list[np.ndarray], fps: int) -> Path:
    """H.264 MP4 of ``(H, W, 3)`` uint8 frames with the ffmpeg that ``imageio-ffmpeg`` ships."""
    import imageio_ffmpeg

    from .io import atomic_output

    height, width = frames[0].shape[:2]
    with atomic_output(path) as tmp:
        writer = imageio_ffmpeg.write_frames(str(tmp), (width, height), fps=fps, codec="libx264", pix_fmt_out="yuv420p",
                                             macro_block_size=2, quality=8, output_params=["-f", "mp4"])
        writer.send(None)
        for frame in frames:
            writer.send(np.ascontiguousarray(frame))
        writer.close()
    return path


def write_gif(path: Path, frames: list[np.ndarray], fps: int) -> Path:
    from PIL import Image

    from .io import atomic_output

    with atomic_output(path) as tmp:
        images = [Image.fromarray(frame) for frame in frames]
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0)
    return path


if __name__ == "__main__":
    sys.exit(main())
