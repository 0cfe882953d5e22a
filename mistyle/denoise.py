"""Denoising path-traced final frames with Intel Open Image Denoise (OIDN, through ``mitsuba-oidn``).

A final frame at the default samples is grainy; OIDN's ``RT`` filter on the linear (HDR) radiance
removes the grain: at the default 64 spp it comes as close to a 2048-spp reference as 16 times the
samples undenoised, in a sixteenth of the time, and the frame-to-frame change of a sequence drops
(``results/denoise/``, ``experiments/denoise_study.py``).

The colour alone is filtered. A noise-free albedo feature (what each pixel's ray sees of the albedo
grid, composited over the background, from the fast layer) was measured too: no closer to the
reference on the held-out pairs, at three to five times the filter's cost, so it is not used.
"""

from __future__ import annotations

import numpy as np

DENOISERS = ("oidn", "none")
"""``mistyle-render --denoise``'s choices: OIDN, or the path tracer's image as it is."""


def oidn_missing() -> str | None:
    """None when OIDN can run here, else a one-line reason with the fix."""
    try:
        import mitsuba_oidn  # noqa: F401
    except ImportError as error:
        return (
            f"OIDN is not available ({error}); install it with pip install mitsuba-oidn nanobind-backend, "
            "or render with --denoise none."
        )
    return None


def denoise(image: np.ndarray, albedo: np.ndarray | None = None) -> np.ndarray:
    """``image (H, W, 3)`` linear radiance, denoised by OIDN's ``RT`` filter in HDR mode; float32, >= 0.
    ``albedo (H, W, 3)``: a noise-free albedo feature to guide the filter (the studies' option)."""
    import mitsuba_oidn

    colour = np.ascontiguousarray(np.maximum(image, 0.0), dtype=np.float32)
    if albedo is None:
        result = mitsuba_oidn.denoise(colour, hdr=True)
    else:
        feature = np.ascontiguousarray(albedo, dtype=np.float32)
        result = mitsuba_oidn.denoise(colour, albedo=feature, hdr=True, clean_aux=True)
    return np.maximum(np.asarray(result, dtype=np.float32), 0.0)
