"""The public API: thin adapters over ``mistyle.pipeline``, the chain ``mistyle-render`` runs.

    import mistyle
    density = mistyle.load_density("smoke.vol")                   # (Z, Y, X)
    albedo = mistyle.stylize(density, "marble.png")               # (Z, Y, X, 3) in [0, 1], feed-forward
    albedo = mistyle.stylize(density, "marble.png", refine=True)  # what mistyle-render path traces by default
    image = mistyle.render(density, albedo, view=0.25, res=256)   # (256, 256, 3) linear RGB
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

For every setting and the results of each stage (timings, the feed-forward and the refined albedo,
the final images), use ``mistyle.Pipeline`` with ``mistyle.PipelineSettings``.

``render`` path-traces the heterogeneous medium with Mitsuba's ``volpath`` in ``llvm_ad_rgb`` on the
CPU (``cuda_ad_rgb`` with ``device="cuda"``).
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import numpy as np

from .conventions import DEFAULT_DENSITY_SCALE, HELD_OUT_VIEW, ORBIT_DISTANCE
from .display import display
from .io import load_density, load_style
from .look import Look, LookSettings
from .pathtrace import path_trace
from .pipeline import Pipeline, PipelineSettings, Stylizer

__all__ = [
    "Look",
    "LookSettings",
    "Pipeline",
    "PipelineSettings",
    "Stylizer",
    "display",
    "fit_look",
    "load_density",
    "load_style",
    "path_trace",
    "render",
    "stylize",
]


@functools.lru_cache(maxsize=2)
def _stylizer(checkpoint, device, vgg_weights) -> Stylizer:
    return Stylizer(checkpoint, device, vgg_weights)


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

    Returns:
        ``(Z, Y, X, 3)`` (or ``(T, Z, Y, X, 3)``) float32 albedo in [0, 1].
    """
    if isinstance(density, (str, os.PathLike)):
        density = load_density(density)
    key = None if checkpoint is None else str(Path(checkpoint).resolve())
    steps = {} if refine else {"refine_steps": 0, "refine_path_steps": 0}
    settings = PipelineSettings(
        checkpoint=key,
        device=device,
        vgg_weights=vgg_weights,
        strength=strength,
        scale_structures=scale_structures,
        colour_match=match_colours,
        **steps,
    )
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
    rendered at (default: the checkpoint's)."""
    if isinstance(density, (str, os.PathLike)):
        from .io import load_density_frames

        density = load_density_frames(density).densities
    key = None if checkpoint is None else str(Path(checkpoint).resolve())
    pipeline_settings = PipelineSettings(
        checkpoint=key, device=device, density_scale=density_scale, scale_structures=scale_structures
    )
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
) -> np.ndarray:
    """Path-trace the medium with Mitsuba's ``volpath``; returns ``(res, res, 3)`` linear RGB.

    Args:
        view: the camera's position on the orbit in [0, 1), as ``--view`` (default: the held-out
            view of evaluations), or a ``mistyle.scenes.View``.
        max_depth: ``-1`` full multiple scattering; ``2`` single scattering.
        density_scale: extinction per unit density (default: the training scale).
        light: ``constant[:Le]``, ``envmap:<file.exr>[:scale]``, ``point:x,y,z[:I]`` or ``area[:L]``.
        coat_ior: a smooth dielectric boundary of this index of refraction (e.g. 1.5); ``None``: none.
        camera_distance: the orbit's radius (the medium box's longest side is 1).
    """
    from .scenes import CameraPath, View
    from .scenes.cameras import validate_orbit_position

    camera = (
        view if isinstance(view, View) else CameraPath(distance=camera_distance).view(validate_orbit_position(view))
    )
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
    return images[0]
