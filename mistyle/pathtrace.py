"""Running the path tracer: images of a medium (``path_trace``) and estimates along the layer's rays.

``path_trace`` renders a density and an albedo grid with Mitsuba's ``volpath`` from several views
of one scene (``scenes.pathtraced_scene`` builds it); everything that shows a final image calls it
(``mistyle.render``, the pipeline, the benchmark). It keeps its scene for the next frame
(``SceneCache``), so a sequence compiles its kernels once. The differentiable path-traced views used in a
fit are ``bridge_torch.PathTracedViews``, since torch meets Dr.Jit only there.

The layer shoots one ray through each pixel centre; Mitsuba's ``mi.render`` averages paths over
each pixel's area. To measure the layer's model error without the point-versus-area difference,
``pixel_centre_estimate`` runs the scene's integrator (e.g. ``volpath``) on the same pixel-centre
rays that the layer uses, many paths per ray.
"""

from __future__ import annotations

import functools
import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .backend import active_variant
from .conventions import DEFAULT_DENSITY_SCALE, IMAGE_SIDES
from .scenes.cameras import split_views
from .stops import raise_if_requested

MAX_PASS_SAMPLES = 1 << 26
"""The most paths one launch of the path tracer may hold (a 256^2 image at 1024 spp): beyond about 2^31
Mitsuba splits a launch itself, into passes whose count must divide ``spp``, and can run out of memory."""

PASS_SAMPLES = 1 << 17
"""Paths per pass of ``path_trace``'s renders: 2 spp of a 256^2 image. A signal (SIGTERM, Ctrl-C) reaches
Python only between launches: one launch of a 256^2 image at 1024 spp takes 60-150 s, one pass of it well
under a second, so a stop waits for one pass at most. Measured on two busy CPU cores, the marble look at
256^2: 0.3-0.45 s a pass (median), 0.66 s at most (a 16^3 blob, ``examples/smoke_64.vol``); 64 passes
took as long as one launch of their samples, as a frozen pass replays its kernels (``render_passes``).
An image of more than ``PASS_SAMPLES`` pixels goes one sample per pixel a pass (1024^2: ~8x as long)."""


def pixel_centre_estimate(scene, spp: int, seed: int, view_count: int, chunk: int = 256) -> np.ndarray:
    """Mean radiance of ``spp`` paths along each pixel-centre ray: ``(V, H, W, 3)`` float32.

    ``scene`` holds a batch sensor of ``view_count`` views (``mistyle.scenes.pathtraced_scene(..., batch=True)``).
    """
    from .integrators import register

    mi = active_variant()
    register()
    from .integrators.single_scatter import pixel_centre_rays

    sensor = scene.sensors()[0]
    width, height = (int(v) for v in sensor.film().crop_size())
    pixels = width * height
    total = np.zeros((pixels, 3))
    for first in range(0, spp, chunk):
        count = min(chunk, spp - first)
        ray, weight, _ = pixel_centre_rays(sensor, count)
        sampler = mi.load_dict({"type": "independent"})
        sampler.seed(seed * 1_000_003 + first, pixels * count)
        radiance, _, _ = scene.integrator().sample(scene, sampler, ray, None, True)
        radiance = radiance * weight
        channels = np.stack([np.asarray(radiance[c]) for c in range(3)], axis=-1)
        total += channels.reshape(pixels, count, 3).sum(axis=1)
    return split_views((total / spp).astype(np.float32).reshape(height, width, 3), view_count)


def two_seed_reference(render, spp: int):
    """Mean of two independent renders and the noise variance of that mean (per value)."""
    first, second = render(spp, 1), render(spp, 2)
    return 0.5 * (first + second), float(np.mean((first - second) ** 2) / 4.0)


def net_rel_rmse(image: np.ndarray, reference: np.ndarray, reference_noise_var: float) -> float:
    """Relative RMSE of ``image`` against a noisy reference, with the reference's noise taken out.

    ``sqrt(max(0, MSE(image, reference) - noise_var)) / RMS(reference)``, where ``noise_var`` is the
    per-value noise variance of the reference (``two_seed_reference`` estimates it).
    """
    mse = float(np.mean((image - reference) ** 2)) - reference_noise_var
    return float(np.sqrt(max(mse, 0.0)) / np.sqrt(np.mean(reference**2)))


def path_trace(
    density,
    albedo,
    views,
    *,
    res: int = 256,
    spp: int = 64,
    max_depth: int = -1,
    density_scale: float = DEFAULT_DENSITY_SCALE,
    light="constant",
    coat_ior: float | None = None,
    coat_mesh=None,
    device: str = "cpu",
    seed: int = 0,
    progress=None,
    bricks: int | None = None,
    max_pass_samples: int | None = None,
) -> tuple[list[np.ndarray], list[float]]:
    """``render`` for several ``View``s of one scene: ``([(res, res, 3)] images, [seconds per view])``.

    ``progress(done, count, seconds)`` is called after each view when given. ``bricks``: voxels per
    brick of the medium's majorant bricks (``scenes.bricks``; the same image in expectation, faster
    on sparse volumes), ``0`` for one medium; by default ``DEFAULT_BRICK``, and 0 under a coat. Renders of
    more than ``PASS_SAMPLES`` paths go in passes (``render_passes``; ``max_pass_samples``: their limit), so
    that a stop asked for by a signal is honoured between passes. ``ValueError`` for settings that render
    every pixel black or NaN: ``max_depth`` 1 (``check_max_depth``), an environment map holding NaN/inf
    (``check_light``).

    The scene is kept for the next call (``SCENES``, a ``SceneCache``): a frame of the same grid shape,
    settings and (bricked) majorant levels updates its grids, face meshes and cameras and renders with
    the kernels compiled for the first, bit for bit as a scene loaded anew. ``release_scenes()`` frees it.
    """
    from .backend import use_variant
    from .scenes import LightSpec
    from .scenes.bricks import DEFAULT_BRICK
    from .volume import validate_albedo, validate_density

    mi = use_variant(device)
    grid = validate_density(density)
    colours = validate_albedo(albedo, grid.shape)
    low, high = IMAGE_SIDES
    if not low <= res <= high or spp < 1:
        raise ValueError(f"Need {low} <= res <= {high} and spp >= 1, got res={res}, spp={spp}.")
    light = light if isinstance(light, LightSpec) else LightSpec.parse(light)
    check_max_depth(max_depth)
    check_light(light)
    if bricks is None:
        bricks = 0 if coat_ior is not None else DEFAULT_BRICK
    options = {
        "res": res,
        "density_scale": density_scale,
        "spp": spp,
        "max_depth": max_depth,
        "light": light,
        "coat_ior": coat_ior,
        "coat_mesh": coat_mesh,
        "seed": seed,
        "bricks": bricks,
    }
    passes = sample_passes(res, spp, PASS_SAMPLES if max_pass_samples is None else max_pass_samples)
    images, seconds = [], []
    with SCENES.lock:  # the kept scene is one: another thread's frame waits rather than rewrite it
        entry = SCENES.frame(mi, grid, colours, views, options)
        for index in range(len(views)):
            raise_if_requested()
            started = time.perf_counter()
            images.append(render_passes(entry.scene, index, passes, seed, entry.render_pass))
            seconds.append(time.perf_counter() - started)
            if progress is not None:
                progress(index + 1, len(views), seconds[-1])
    return images, seconds


def _frozen_pass():
    """A frozen ``mi.render`` of one pass (``render_passes``), for one scene object: its recordings
    hold the kernels of that scene's structure, which a scene of other settings (``max_depth``, a
    medium's bounds: literals in the kernel, invisible to ``dr.freeze``'s key) does not share."""
    import drjit as dr

    mi = active_variant()

    # Passes differ in their seed alone (an opaque UInt32): the kernels are compiled once, and freezing
    # spares re-tracing the integrator at each pass (30-60 ms on two cores, 10-20% of a pass; a replay: 1 ms).
    # ``count`` and ``sensor`` are Python ints, part of the frozen function's key: near-equal passes take
    # two sizes at most. Kept across frames (``SceneCache``), it replays a frame of one medium; a bricked
    # frame re-records once (a trace of the integrator, whose kernels are compiled already): measured,
    # new vertices in more than one face mesh plus the scene's rebuild re-record even with the same data,
    # a cause not found in dr.freeze's log. A new function per frame recorded three times. So no warning
    # for re-recording, and the recordings kept are bounded (the least recently used go).
    @dr.freeze(warn_after=1 << 30, limit=8)
    def render_pass(scene, sensor, count, pass_seed):
        return mi.render(scene, sensor=sensor, spp=count, seed=pass_seed)

    return render_pass


@dataclass
class KeptScene:
    """A loaded scene with the settings it was built for (``key``), its frozen pass and the views its
    sensors show now."""

    key: tuple
    scene: object
    render_pass: object
    views: list


class SceneCache:
    """The scene of the last ``path_trace``, kept so that the next frame of the same structure updates
    its data (``scenes.update_pathtraced_scene``: grids, majorants, face meshes, cameras through
    ``mi.traverse``) instead of loading a new scene, and renders with the kernels already compiled.

    Why one scene and not a few: Dr.Jit traces a call to a medium (or shape) for every live instance
    of its class, so a second scene kept alive changes the kernel of the first (a compilation); a new
    structure releases the old scene before loading its own, which then reuses its instance ids.
    Frames with a coat mesh (a file) are loaded anew each time. ``release()`` frees the grids held.

    ``builds`` and ``updates`` count the scenes loaded and the frames that reused one (tests, reports).
    """

    def __init__(self):
        self.lock = threading.RLock()
        self.kept: KeptScene | None = None
        self.builds = 0
        self.updates = 0

    def release(self) -> None:
        with self.lock:
            self.kept = None

    def frame(self, mi, density: np.ndarray, albedo: np.ndarray, views: list, options: dict) -> KeptScene:
        """The kept scene set to this frame, or a new one for it (``path_trace``'s ``options``)."""
        from .scenes import pathtraced_scene, update_pathtraced_scene
        from .scenes.bricks import DEFAULT_LEVELS, brick_levels

        with self.lock:
            bricks = options["bricks"]
            split = brick_levels(density, bricks, DEFAULT_LEVELS) if bricks else None
            key = self.structure(mi, density, views, options, split)
            if key is not None and self.kept is not None and self.kept.key == key:
                # Cameras left where they are when the views are too: their update runs a kernel of its own.
                moved = None if list(views) == self.kept.views else views
                try:
                    params = mi.traverse(self.kept.scene)
                    update_pathtraced_scene(params, density, albedo, moved, bricks=bricks, brick_split=split)
                    params.update()
                except BaseException:
                    self.kept = None  # half updated: never render it again
                    raise
                self.kept.views = list(views)
                self.updates += 1
                return self.kept
            self.kept = None  # first: its objects' instance ids go back for the new scene's
            scene = mi.load_dict(pathtraced_scene(density, albedo, views, **options, brick_split=split))
            kept = KeptScene(key, scene, _frozen_pass(), list(views))
            self.builds += 1
            if key is not None:
                self.kept = kept
            return kept

    @staticmethod
    def structure(mi, density: np.ndarray, views: list, options: dict, split) -> tuple | None:
        """What a kept scene must share with a frame to be updated to it (``None``: never kept): the
        variant, the grid's shape, the number of views, every setting, the present brick levels, and an
        environment map's file's time and size (its pixels are loaded with the scene)."""
        from .scenes.bricks import present_levels

        if options["coat_mesh"] is not None:
            return None
        light = options["light"]
        stamp = None
        if light.kind == "envmap":
            stat = os.stat(light.filename)
            stamp = (stat.st_mtime_ns, stat.st_size)
        settings = tuple(sorted((name, value) for name, value in options.items() if name != "coat_mesh"))
        levels = present_levels(split[0]) if split is not None else None
        return (mi.variant(), tuple(density.shape), len(views), settings, stamp, levels)


SCENES = SceneCache()
"""The one ``SceneCache`` of this process, which ``path_trace`` renders through."""


KEPT_SCENE_VOXELS = 256**3
"""The largest grid whose scene outlives the frames of one ``Pipeline.path_trace``: a 512^3 grid's scene
holds about 7 GB (``results/memory_trace/``), which a command would keep while it writes its files."""


def release_scenes() -> None:
    """Free the scene that ``path_trace`` keeps for the next frame (its grids, on the device too), and
    return the memory Dr.Jit kept of it to the system."""
    import drjit as dr

    SCENES.release()
    dr.flush_malloc_cache()


def render_passes(scene, sensor: int, passes: list[int], seed: int, render_pass=None) -> np.ndarray:
    """View ``sensor`` of a loaded ``scene`` in ``passes`` (samples per pixel of each, ``sample_passes``):
    ``(H, W, 3)`` float32, the mean of the passes weighted by their samples. With a box filter each pixel
    is the mean of its samples, so this is the estimator of one launch of ``sum(passes)`` samples: the same
    expectation and noise. One pass is the sensor's own launch (its ``spp`` and seed ``seed + sensor``,
    what the exported ``scene.xml`` renders); pass ``n`` of ``P`` is seeded ``(seed + sensor) * P + n``.
    ``render_pass``: the scene's frozen pass (``_frozen_pass``), kept with the scene across frames; by
    default a new one.

    A stop asked for by a signal is raised between passes (``stops.raise_if_requested``, should the
    handler's own exception have been lost)."""
    mi = active_variant()
    if len(passes) == 1:
        return np.array(mi.render(scene, sensor=sensor), dtype=np.float32)
    render_pass = _frozen_pass() if render_pass is None else render_pass
    total = None
    for number, count in enumerate(passes):
        raise_if_requested()
        pass_seed = ((seed + sensor) * len(passes) + number) % (1 << 32)
        image = np.array(render_pass(scene, sensor, count, mi.UInt32(pass_seed)), dtype=np.float64) * count
        total = image if total is None else total + image
    return (total / sum(passes)).astype(np.float32)


def sample_passes(res: int, spp: int, max_pass_samples: int = MAX_PASS_SAMPLES) -> list[int]:
    """Samples per pixel of each pass of a ``res``^2 image at ``spp``: one pass when ``res^2 spp`` fits
    ``max_pass_samples``, else as few near-equal passes as fit (their sum is ``spp``; at least one
    sample per pixel each, so at ``res^2 > max_pass_samples`` a pass holds ``res^2`` paths).

    One launch of ``res^2 spp`` paths beyond about 2^31 makes Mitsuba split it into passes whose count
    must divide ``spp`` (an error otherwise) and can run out of memory; passes of our own avoid both.
    ``path_trace`` splits at ``PASS_SAMPLES``, far below that, so that a stop waits for one pass."""
    pixels = res * res
    per_pass = max(1, max_pass_samples // pixels)
    if spp <= per_pass:
        return [spp]
    count = -(-spp // per_pass)
    return [spp // count + (1 if number < spp % count else 0) for number in range(count)]


# ---------------------------------------------------------------------------- renders that cannot show the medium
MIN_MEDIUM_PIXELS = 16
"""The fewest pixels, or 1% of an image smaller than 40^2, in which a final image must see the medium:
fewer show nothing of a style (the smallest patch the metrics compare is 5x5)."""

DARK_MARGIN = 10.0
"""How far below ``FOREGROUND_THRESHOLD`` the brightest radiance a medium could scatter must lie for a
render to be refused before it runs: the bound of ``medium_radiance_bound`` is an estimate (its ray
runs along a grid axis; a diagonal one can be sqrt(3) times as long)."""


def check_max_depth(max_depth: int, name: str = "max_depth (--max-depth)") -> None:
    """``ValueError`` for ``max_depth`` 1: Mitsuba's ``volpath`` then ends every path at its first
    segment, the camera ray, which sees only the light itself (hidden in mistyle's renders) and never
    light that the medium scatters; every pixel is black."""
    if max_depth == 1:
        raise ValueError(
            f"{name} 1 renders black: a path of one segment is the camera ray alone, which sees only the "
            "light directly (hidden, so the background is black) and never light scattered by the medium. "
            "Light reaches the medium from a depth of 2: use 2 for single scattering or -1 for full "
            "multiple scattering."
        )


@functools.lru_cache(maxsize=8)
def _environment_values(path: str, modified: int, size: int) -> tuple[int, tuple[int, int] | None, float]:
    """``(pixels holding NaN/inf, the first such (row, column), the largest finite value)`` of the image
    at ``path``, read as Mitsuba's ``envmap`` reads it; cached by the file's time and size. An OpenEXR
    file is read by ``io.load_envmap``, which refuses a truncated file and NaN, infinite or negative
    pixels in one line; other formats as Mitsuba reads them."""
    from .files import load_envmap

    if Path(path).suffix.lower() == ".exr":
        values = load_envmap(path)
    else:
        try:
            values = np.array(active_variant().Bitmap(path), dtype=np.float32)
        except RuntimeError as error:
            raise ValueError(f"The environment map {path} cannot be read ({str(error).strip()[:120]}).") from None
    values = values.reshape(values.shape[0], values.shape[1], -1)
    bad = ~np.isfinite(values).all(axis=-1)
    first = tuple(int(i) for i in np.argwhere(bad)[0]) if bad.any() else None
    finite = values[np.isfinite(values)]
    return int(bad.sum()), first, float(finite.max()) if finite.size else 0.0


def environment_values(path) -> tuple[int, tuple[int, int] | None, float]:
    """``_environment_values`` of the environment map at ``path``."""
    import os

    stat = os.stat(path)
    return _environment_values(str(path), stat.st_mtime_ns, stat.st_size)


def check_light(light) -> None:
    """``ValueError`` for a light that renders NaN: an environment map holding NaN/inf pixels. Mitsuba
    builds the map's sampling distribution from every pixel, so a few of them make every path that
    meets the map NaN (and the denoiser then turns the image black)."""
    if light.kind != "envmap":
        return
    bad, first, _ = environment_values(light.filename)
    if bad:
        raise ValueError(
            f"The environment map {light.filename} holds {bad} NaN/inf pixel(s) (first at row {first[0]}, column "
            f"{first[1]}), which make every path that meets it NaN. Clean it (e.g. np.nan_to_num(image, nan=0.0, "
            "posinf=0.0) and write it again), or choose another light."
        )


def light_radiance(light, shape_zyx) -> float:
    """The largest radiance ``light`` (a ``scenes.LightSpec``) sends into the medium box of ``shape_zyx``
    from any direction, as an isotropic medium scatters it: a constant or an area light's radiance, an
    environment map's brightest pixel times its scale, a point light's intensity / (4 pi d^2) at the
    box's nearest point (inf inside the box)."""
    from .scenes.box import MediumBox

    if light.kind == "envmap":
        return light.value * environment_values(light.filename)[2]
    if light.kind == "point":
        box = MediumBox(tuple(shape_zyx))
        gap = np.maximum(0.0, np.maximum(box.bbox_min - light.position, np.asarray(light.position) - box.bbox_max))
        distance = float(np.linalg.norm(gap))
        return light.value / (4.0 * np.pi * distance**2) if distance > 0 else float("inf")
    return light.value


def optical_depth(density, density_scale: float) -> float:
    """The largest optical depth through the medium box along a grid axis: ``density_scale`` times the
    largest sum of a row of voxels times a voxel's side (the box's longest side is 1)."""
    grid = np.asarray(density, dtype=np.float64)
    voxel = 1.0 / max(grid.shape)
    return float(density_scale) * voxel * max(float(grid.sum(axis=axis).max()) for axis in range(3))


def medium_radiance_bound(density, density_scale: float, light) -> float:
    """About the brightest radiance a white medium can send to the camera: the light's radiance
    (``light_radiance``) times the fraction of it that the densest ray scatters, ``1 - exp(-tau)``
    (``optical_depth``; multiple scattering adds little where this is small)."""
    return light_radiance(light, np.shape(density)) * -np.expm1(-optical_depth(density, density_scale))


def medium_span(density, view, res: int) -> float:
    """How many pixels across the medium (the box around its non-zero voxels) appears in a ``res``^2
    image from ``view`` (a ``scenes.View``): the larger side of the rectangle around its projected
    corners; inf when a corner lies at or behind the camera."""
    return medium_extent(density, view, res)[0]


def medium_width(density, view, res: int) -> float:
    """How many pixels the medium's projected box is across where narrowest (``medium_extent``)."""
    return medium_extent(density, view, res)[1]


def medium_extent(density, view, res: int) -> tuple[float, float]:
    """``(span, width)`` in pixels of the medium's box projected from ``view``: ``medium_span``, and its least
    width over directions a degree apart (a filament, seen edge-on); inf behind the camera, 0 when empty."""
    corners = _projected_box(density, view, res)
    if corners is None:
        return float("inf"), float("inf")
    if not len(corners):
        return 0.0, 0.0
    angles = np.radians(np.arange(180.0))
    width = np.ptp(corners @ np.stack([np.cos(angles), np.sin(angles)]), axis=0).min()
    return float(np.ptp(corners, axis=0).max()), float(width)


def _projected_box(density, view, res: int) -> np.ndarray | None:
    """The 8 corners of the box around ``density``'s non-zero voxels in pixels of a ``res``^2 image from
    ``view``, ``(8, 2)`` (none when the density is empty); None when a corner lies at or behind the camera."""
    from .scenes.box import MediumBox

    grid = np.asarray(density)
    box = MediumBox(grid.shape)
    occupied = grid > 0
    if not occupied.any():
        return np.zeros((0, 2))
    ranges = []  # (first, last + 1) occupied voxel along x, y, z
    for axis in (2, 1, 0):
        present = np.flatnonzero(occupied.any(axis=tuple(a for a in range(3) if a != axis)))
        ranges.append((present[0], present[-1] + 1))
    low = box.bbox_min + np.array([first for first, _ in ranges]) * box.voxel_size
    high = box.bbox_min + np.array([last for _, last in ranges]) * box.voxel_size
    corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])])
    origin = np.asarray(view.origin)
    forward = np.subtract(view.target, origin)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, view.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    offsets = corners - origin
    depth = offsets @ forward
    if (depth <= 1e-9).any():
        return None
    focal = res / (2.0 * np.tan(np.radians(view.fov_deg) / 2.0))  # the fov spans the image's width
    return np.stack([(offsets @ right) / depth * focal, (offsets @ up) / depth * focal], axis=1)


def medium_pixels(image: np.ndarray) -> int:
    """How many pixels of a linear render ``(H, W, 3)`` see the medium (``FOREGROUND_THRESHOLD``)."""
    from .conventions import FOREGROUND_THRESHOLD

    return int(np.count_nonzero(np.asarray(image).max(axis=-1) > FOREGROUND_THRESHOLD))


def min_medium_pixels(res: int) -> int:
    """``MIN_MEDIUM_PIXELS``, or 1% of a ``res``^2 image smaller than 40^2 (at least one pixel)."""
    return max(1, min(MIN_MEDIUM_PIXELS, res * res // 100))


def _too_far(view, res: int, pixels: float) -> str:
    distance = float(np.linalg.norm(np.subtract(view.origin, view.target)))
    half = distance * pixels / (res / 2.0)  # the medium's picture shrinks as 1/distance
    return (
        f"the camera is too far: at distance {distance:g} the medium spans {pixels:.2g} pixel(s) of the "
        f"{res}^2 image, too few to show it in the {min_medium_pixels(res)} pixels a final image needs. "
        f"Move the camera closer (--camera-distance, camera_distance; at about {half:.2g} the medium spans half the "
        "image) or raise the resolution (--res)."
    )


def _too_faint(density, density_scale: float, light, bound: float) -> str:
    """Why a medium whose radiance is at most ``bound`` cannot show: too thin when an optical depth of 1
    would show it under this light, else the light too dim."""
    from .conventions import FOREGROUND_THRESHOLD

    radiance = light_radiance(light, np.shape(density))
    if radiance * -np.expm1(-1.0) >= DARK_MARGIN * FOREGROUND_THRESHOLD:
        return _too_thin(density, density_scale, light, bound)
    lit = radiance * -np.expm1(-max(optical_depth(density, density_scale), 1.0))
    return (
        f"the {light.kind} light is too dim to show the medium: it sends the medium a radiance of at most "
        f"{radiance:.2g}, so the medium shows at most {bound:.2g} (a pixel shows the medium above "
        f"{FOREGROUND_THRESHOLD:g}). Make the light about {DARK_MARGIN * FOREGROUND_THRESHOLD / lit:.3g} times as "
        "strong (--light, e.g. constant:8, point:x,y,z:<intensity>), or move it closer."
    )


def _too_thin(density, density_scale: float, light, bound: float) -> str:
    from .conventions import FOREGROUND_THRESHOLD, MAX_DENSITY_SCALE

    tau = optical_depth(density, density_scale)
    largest = float(np.max(density))
    what = (
        f"the medium is too thin to see at density scale {density_scale:g}: the densest ray through it has an "
        f"optical depth of {tau:.2g}, so under the light's radiance of {light_radiance(light, np.shape(density)):.3g} "
        f"it shows at most {bound:.2g} (a pixel shows the medium above {FOREGROUND_THRESHOLD:g})."
    )
    wanted = density_scale / tau if tau > 0 else float("inf")
    if largest < np.finfo(np.float32).tiny:
        return (
            f"{what} The density's values are at most {largest:.2g}, below float32's normal range, which the path "
            "tracer reads as 0: normalise the density (density / density.max()) and set the extinction with the "
            f"density scale (--density-scale, density_scale; the default is {DEFAULT_DENSITY_SCALE:g})."
        )
    if wanted > MAX_DENSITY_SCALE:
        normalised = density_scale * largest / tau
        return (
            f"{what} The density's largest value is {largest:.2g}: normalise it (density / density.max()); then a "
            f"density scale (--density-scale, density_scale) of {normalised:.3g} or more gives that ray an optical "
            f"depth of 1 (the default is {DEFAULT_DENSITY_SCALE:g})."
        )
    return (
        f"{what} Raise the density scale (--density-scale, density_scale) to {wanted:.3g} or more, which gives "
        f"that ray an optical depth of 1 (the default is {DEFAULT_DENSITY_SCALE:g})."
    )


def unseen_medium(density, view, res: int, density_scale: float, light) -> str | None:
    """Why a render of ``density`` from ``view`` cannot show its medium, decided from the inputs alone,
    or None: a camera so far that the medium spans fewer than sqrt(``min_medium_pixels``) pixels
    (``medium_span``: its picture cannot hold that many), or a medium too thin, or a light too dim, to
    show it with ``DARK_MARGIN`` to spare."""
    from .conventions import FOREGROUND_THRESHOLD

    pixels = medium_span(density, view, res)
    if pixels < np.sqrt(min_medium_pixels(res)):
        return _too_far(view, res, pixels)
    bound = medium_radiance_bound(density, density_scale, light)
    if bound * DARK_MARGIN < FOREGROUND_THRESHOLD:
        return _too_faint(density, density_scale, light, bound)
    return None


def dark_render(image: np.ndarray, density, albedo, view, res: int, density_scale: float, light) -> str | None:
    """Why the final ``image`` of ``density`` with ``albedo`` from ``view`` shows the medium in fewer
    than ``min_medium_pixels`` pixels, or None when it shows it: the medium too thin or the light too dim
    (a white medium would stay within ``DARK_MARGIN`` of ``FOREGROUND_THRESHOLD``), the albedo black, the
    camera too far (the medium spans under a quarter of the image), else the light's place or the view."""
    from .conventions import FOREGROUND_THRESHOLD

    seen, needed = medium_pixels(image), min_medium_pixels(res)
    if seen >= needed:
        return None
    shown = f"the medium shows in {seen} pixel(s) of the {res}^2 image (a final image needs {needed})"
    bound = medium_radiance_bound(density, density_scale, light)
    brightest = float(np.asarray(albedo)[np.asarray(density) > 0].max(initial=0.0))
    pixels, narrow = medium_extent(density, view, res)
    if bound < DARK_MARGIN * FOREGROUND_THRESHOLD:
        return f"{shown}: {_too_faint(density, density_scale, light, bound)}"
    if bound * brightest < DARK_MARGIN * FOREGROUND_THRESHOLD:
        return (
            f"{shown}: the albedo is black where there is medium (at most {brightest:.2g}), so the medium absorbs "
            "the light it meets and shows as black on black. Check the style or the look that made the albedo."
        )
    if pixels < res / 4.0:
        return f"{shown}: {_too_far(view, res, pixels)}"
    if narrow < 2.0:
        return (
            f"{shown}: the medium is {pixels:.0f} pixels long but {narrow:.2g} across, thinner than the pixels "
            "that would show it. Raise the resolution (--res), move the camera closer (--camera-distance) or "
            "raise --density-scale so that it covers its pixels."
        )
    return (
        f"{shown}, though the medium spans {pixels:.0f} pixels and could scatter a radiance up to {bound:.2g}: "
        f"the {light.kind} light may not reach the medium from where it is, or the medium lies outside the view. "
        "Check --light and --view."
    )
