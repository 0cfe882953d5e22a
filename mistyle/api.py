"""The public API: thin adapters over ``mistyle.pipeline``, the chain ``mistyle-render`` runs.

    import mistyle
    density = mistyle.load_density("smoke.vol")                   # (Z, Y, X)
    albedo = mistyle.stylize(density, "marble.png")               # (Z, Y, X, 3) in [0, 1], feed-forward
    albedo = mistyle.stylize(density, "marble.png", refine=True)  # what mistyle-render path traces by default
    image = mistyle.render(density, albedo, view=0.25, res=256)   # (256, 256, 3) linear RGB, denoised
    png_values = mistyle.display(image)                           # the PNGs' tone curve

``stylize`` runs the trained SKPN (the bundled checkpoint unless one is named) and the colour match
on numpy arrays of any ``D, H, W``, single frames ``(Z, Y, X)`` or sequences ``(T, Z, Y, X)``; with
``refine=True`` it returns what ``mistyle-render`` path traces by default: at full strength, a look
fitted on the frame, or on a sequence's first, middle and last frame, and applied to every frame
(``Pipeline.fits_look``), else the refinement ``Pipeline.refinement`` gives. ``strength`` fades
the style towards a uniform grey medium and a list of ``(style, weight)`` pairs mixes styles; both
act on the predicted stylizing kernels (``Stylizer.kernels``, ``Stylizer.weakened``), not on
finished albedos:

    albedo = mistyle.stylize(density, [("wave.png", 0.7), ("starry.png", 0.3)], strength=0.5)

A sequence is stylized best from a look, fitted once on its key frames and applied to every frame
(``mistyle.look``; ``mistyle-render --save-look`` / ``--look``); to keep the look, or choose its
key frames:

    look = mistyle.fit_look(frames, "wave.png")       # frames (T, Z, Y, X), a list, or a folder's path
    albedos = look.stylize(frames)                     # one albedo per frame, each from its own density
    albedos = look.stylize(frames, velocities=vel)     # its texture carried by the frames' (T, Z, Y, X, 3) velocities

For every setting and the results of each stage (timings, the feed-forward and the refined albedo,
the final images), use ``mistyle.Pipeline`` with ``mistyle.PipelineSettings``.

``render`` path-traces the heterogeneous medium with Mitsuba's ``volpath`` in ``llvm_ad_rgb`` on the
CPU (``cuda_ad_rgb`` with ``device="cuda"``).

Every function checks its arguments before any work, with the command line's ranges: a ``TypeError``
or ``ValueError`` of one line that names the argument and what it takes, and a ``BackendError`` for
``device="cuda"`` on a machine without a usable GPU.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import numpy as np

from . import files as _files
from . import tone as _tone
from .backend import check_device
from .conventions import DEFAULT_DENSITY_SCALE, HELD_OUT_VIEW, ORBIT_DISTANCE
from .look import Look, LookSettings
from .pathtrace import path_trace
from .pipeline import Pipeline, PipelineSettings, RenderSettings
from .pipeline.settings import described, validate_flag, validate_int, validate_path, validate_real
from .resample import DEFAULT_WORKING_SIZE
from .style import style_parts
from .stylizer import Stylizer, checked_frames

__all__ = [
    "Look",
    "LookSettings",
    "Pipeline",
    "PipelineSettings",
    "RenderSettings",
    "Stylizer",
    "display",
    "fit_look",
    "load_density",
    "load_style",
    "path_trace",
    "render",
    "stylize",
]

MAX_SEED = (1 << 31) - 1
"""The largest ``render(seed=...)``: Mitsuba takes 32-bit unsigned seeds, and a render derives more from
``seed`` (one per further view, and per sample pass of large renders), which must fit too."""


# ---------------------------------------------------------------------------- argument checks
# Each raises one line naming the argument and what it takes, before any work (the command line's
# own checks are render_final.check_options; the ranges shared with it live in pipeline.RenderSettings).
def _device(device) -> str:
    return check_device(device, cpu_option='device="cpu"')


def _frame_count(density) -> int:
    """How many frames ``density`` (a frame, a sequence ``(T, Z, Y, X)`` or a list of frames) holds, each
    checked as the pipeline checks them (``stylizer.checked_frames``); ``ValueError`` for none."""
    if isinstance(density, (list, tuple)):
        count = len(density)
    else:
        density = np.asarray(density)
        count = density.shape[0] if density.ndim == 4 and density.shape[-1] != 1 else 1
    if count == 0:
        raise ValueError(
            f"density holds no frames ({described(density)}); give a frame (Z, Y, X), a sequence (T, Z, Y, X) "
            "with T >= 1, a list of frames or a density file's path."
        )
    return len(checked_frames(density)[0])


def _style(style_image, name: str = "style_image", mixes: bool = True) -> None:
    """The style's form: a path, an ``(H, W, C)`` array or (``mixes``) a mix ``[(style, weight), ...]``."""
    accepted = "an image's path, an (H, W, 3) array, a PIL image" + (
        " or a mix [(style, weight), ...]" if mixes else " or the like"
    )
    for image, _ in style_parts(style_image) if mixes else [(style_image, 1.0)]:
        array_like = hasattr(image, "__array_interface__") or hasattr(image, "__array__")  # PIL, torch
        if not (isinstance(image, (str, os.PathLike, np.ndarray)) or array_like):
            raise TypeError(f"{name} must be {accepted}; got {described(image)}.")


def _key_frames(key_frames, frame_count: int):
    if key_frames is None:
        return None
    if isinstance(key_frames, (str, bytes)) or not hasattr(key_frames, "__iter__"):
        raise TypeError(f"key_frames must be a list of frame indices such as [0, 40, 80], got {described(key_frames)}.")
    keys = [validate_int(key, "each of key_frames") for key in key_frames]
    outside = [key for key in keys if not 0 <= key < frame_count]
    if outside:
        raise ValueError(
            f"key_frames must index the density's {frame_count} frame(s), 0 to {frame_count - 1}; got {outside}."
        )
    return keys


# ---------------------------------------------------------------------------- the API
@functools.lru_cache(maxsize=2)
def _stylizer(checkpoint, device, vgg_weights) -> Stylizer:
    return Stylizer(checkpoint, device, vgg_weights)


def load_density(path, grid: str | None = None) -> np.ndarray:
    """``io.load_density``: a density ``(Z, Y, X)`` from a ``.vol``, ``.vdb``, ``.npy`` or ``.npz`` file."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path must be a density file's path (a str or Path), got {described(path)}.")
    if grid is not None and not isinstance(grid, str):
        raise TypeError(f"grid must be a .vdb grid's name (a str) or None, got {described(grid)}.")
    return _files.load_density(path, grid)


def load_style(style, notes: list | None = None) -> np.ndarray:
    """``io.load_style``: a style picture as float32 ``(H, W, 3)`` display RGB in [0, 1], from a path or an
    array; ``notes`` (a list) collects the conversions made."""
    _style(style, "style", mixes=False)
    if notes is not None and not isinstance(notes, list):
        raise TypeError(f"notes must be a list (the conversions are appended) or None, got {described(notes)}.")
    return _files.load_style(style, notes)


def display(image) -> np.ndarray:
    """Linear radiance ``(..., 3)`` -> float32 display values in [0, 1]: the tone curve of mistyle's PNGs
    (``tone.display``). ``ValueError`` for NaN or inf, which have no display value."""
    array = np.asarray(image)
    if not (np.issubdtype(array.dtype, np.number) or array.dtype == np.bool_) or np.iscomplexobj(array):
        raise TypeError(f"image must hold real numbers (linear RGB radiance), got dtype {array.dtype}.")
    bad = ~np.isfinite(array)
    if bad.any():
        raise ValueError(
            f"image holds {int(bad.sum())} NaN/inf value(s) of {array.size} (first at index "
            f"{tuple(int(i) for i in np.argwhere(bad)[0])}), which have no display value; clean it first, "
            "e.g. np.nan_to_num(image, nan=0.0) (inf then shows white)."
        )
    return _tone.display(array)


def stylize(
    density,
    style_image,
    checkpoint=None,
    scale_structures: float = 1.0,
    device: str = "cpu",
    vgg_weights=None,
    strength: float = 1.0,
    match_colours: bool = True,
    refine: bool = False,
    working_size: int = DEFAULT_WORKING_SIZE,
) -> np.ndarray:
    """Albedo for ``density`` in the look of ``style_image``: the network's arrangement with the
    style's colours (``colour_match``), and with ``refine=True`` refined against the style.

    Args:
        density: ``(Z, Y, X)`` or a sequence ``(T, Z, Y, X)``, finite, >= 0, not all zero; or a density
            file's path (``load_density``).
        style_image: a path, or an ``(H, W, 3)`` array (uint8, uint16 or float in [0, 1]), or a mix
            ``[(style, weight), ...]`` (weights >= 0, normalised to sum 1).
        strength: 0 gives a uniform grey medium of the styled one's brightness, 1 the full style.
        checkpoint: a ``python -m mistyle.train`` checkpoint; default: the bundled one.
        scale_structures: resample the density by this factor before stylizing (paper Sec. 5.5):
            > 1 makes the style's structures smaller relative to the volume.
        match_colours: False gives the network's albedo as predicted, without the colour match.
        refine: False: feed-forward, no gradient step (``mistyle-render --refine 0``, under a second
            at 64^3). True: the albedo ``mistyle-render`` path traces with its defaults (at full
            strength a look fitted on the frame or on a sequence's key frames, tens of seconds,
            ``Pipeline.fits_look``; weakened styles are not refined, see ``Pipeline.refinement``).
        working_size: a grid longer than this on a side is stylized on a copy resampled to it, and
            its albedo resampled back (``mistyle.resample``); 0 stylizes the full grid.

    Returns:
        ``(Z, Y, X, 3)`` (or ``(T, Z, Y, X, 3)``) float32 albedo in [0, 1].
    """
    validate_path(checkpoint, "checkpoint", "a mistyle-train checkpoint's path")
    validate_flag(match_colours, "match_colours")
    validate_flag(refine, "refine")
    _device(device)
    key = None if checkpoint is None else str(Path(checkpoint).resolve())
    steps = {} if refine else {"refine_steps": 0, "refine_path_steps": 0}
    settings = PipelineSettings(
        checkpoint=key,
        device=device,
        vgg_weights=vgg_weights,
        strength=strength,
        scale_structures=scale_structures,
        working_size=working_size,
        colour_match=match_colours,
        **steps,
    )
    _style(style_image)
    if isinstance(density, (str, os.PathLike)):
        density = load_density(density)
    _frame_count(density)
    stylized = Pipeline(settings, stylizer=_stylizer(key, device, vgg_weights)).stylize(density, style_image)
    return np.stack(stylized.albedos) if stylized.frames.sequence else stylized.albedos[0]


def fit_look(
    density,
    style_image,
    key_frames=None,
    checkpoint=None,
    device: str = "cpu",
    density_scale: float | None = None,
    scale_structures: float = 1.0,
    settings: LookSettings | None = None,
) -> Look:
    """A ``Look`` of ``style_image`` fitted on the ``key_frames`` (default: the first, middle and last) of
    ``density`` (a frame ``(Z, Y, X)``, a sequence ``(T, Z, Y, X)``, a list of frames, or a path), as
    ``mistyle-render --save-look`` fits it; ``look.stylize(frame)`` applies it, ``look.save(path)``
    writes it and ``Look.load(path)`` reads it back. ``density_scale``: the scale the frames will be
    rendered at (default: the checkpoint's); ``settings``: a ``LookSettings`` (default: ``--save-look``'s)."""
    validate_path(checkpoint, "checkpoint", "a mistyle-train checkpoint's path")
    _device(device)
    if settings is not None and not isinstance(settings, LookSettings):
        raise TypeError(
            f"settings must be a LookSettings (e.g. mistyle.LookSettings(steps=30)) or None, got {described(settings)}."
        )
    key = None if checkpoint is None else str(Path(checkpoint).resolve())
    pipeline_settings = PipelineSettings(
        checkpoint=key, device=device, density_scale=density_scale, scale_structures=scale_structures
    )
    _style(style_image)
    if isinstance(density, (str, os.PathLike)):
        density = _files.load_density_frames(density).densities
    key_frames = _key_frames(key_frames, _frame_count(density))
    pipeline = Pipeline(pipeline_settings, stylizer=_stylizer(key, device, None))
    return pipeline.fit_look(density, style_image, key_frames=key_frames, look_settings=settings)


def render(
    density,
    albedo,
    view: float = HELD_OUT_VIEW,
    res: int = 256,
    spp: int = 64,
    max_depth: int = -1,
    density_scale: float = DEFAULT_DENSITY_SCALE,
    light: str = "constant",
    coat_ior: float | None = None,
    coat_mesh=None,
    camera_distance: float = ORBIT_DISTANCE,
    device: str = "cpu",
    seed: int = 0,
    denoise: str = "oidn",
) -> np.ndarray:
    """Path-trace the medium with Mitsuba's ``volpath``; returns ``(res, res, 3)`` linear RGB, denoised as
    ``mistyle-render`` denoises its images (``denoise="none"``: the path tracer's own estimate).

    Args:
        view: the camera's position on the orbit in [0, 1), as ``--view`` (default: the held-out
            view of evaluations), or a ``mistyle.scenes.View``.
        max_depth: ``-1`` full multiple scattering; ``2`` single scattering.
        density_scale: extinction per unit density (default: the training scale).
        light: ``constant[:Le]``, ``envmap:<file.exr>[:scale]``, ``point:x,y,z[:I]`` or ``area[:L]``.
        coat_ior: a smooth dielectric boundary of this index of refraction (e.g. 1.5); ``None``: none.
        camera_distance: the orbit's radius (the medium box's longest side is 1).
        seed: the sampler's seed, in [0, ``MAX_SEED``].
        denoise: ``"oidn"`` (Intel Open Image Denoise, ``mistyle-render``'s default) or ``"none"``.
    """
    from .scenes import CameraPath, LightSpec, View, validate_density_scale
    from .scenes.cameras import validate_camera_distance, validate_orbit_position
    from .volume import validate_albedo, validate_density

    RenderSettings(res=res, spp=spp, max_depth=max_depth, coat_ior=coat_ior, denoise=denoise)  # the command's ranges
    validate_density_scale(validate_real(density_scale, "density_scale"))
    validate_int(seed, "seed", 0, MAX_SEED)
    if not isinstance(light, (str, LightSpec)):
        raise TypeError(
            "light must be a string: constant[:Le], envmap:<file.exr>[:scale], point:x,y,z[:intensity] or "
            f"area[:radiance] (default 'constant'); got {described(light)}."
        )
    if isinstance(light, str):
        try:
            light = LightSpec.parse(light)
        except ValueError as error:  # the parser's messages name the command line's option
            raise ValueError(str(error).replace("--light", "light", 1)) from None
    _device(device)
    if isinstance(view, View):
        camera = view
    else:
        position = validate_real(view, "view", "an orbit position in [0, 1) or a mistyle.scenes.View")
        distance = validate_real(camera_distance, "camera_distance")
        camera = CameraPath(distance=validate_camera_distance(distance, "camera_distance")).view(
            validate_orbit_position(position)
        )
    validate_albedo(albedo, validate_density(density).shape)
    images, _ = path_trace(
        density,
        albedo,
        [camera],
        res=res,
        spp=spp,
        max_depth=max_depth,
        density_scale=density_scale,
        light=light,
        coat_ior=coat_ior,
        coat_mesh=coat_mesh,
        device=device,
        seed=seed,
    )
    if denoise == "oidn":
        from .denoise import denoise as denoise_image
        from .stylizer import check_finite

        check_finite("The path-traced image", images)  # before the denoiser, which hides NaN
        return denoise_image(images[0])
    return images[0]
