"""Smooth noise fields fixed in a grid's box: the SKPN's noise inputs.

The density alone decides where the SKPN's features vary, so without another input every style's
colours follow the density's arrangement (``docs/decisions/2026-12-02-noise-site.md``). The noise site
adds, before the decoder's tanh, a style-weighted sum of these fields: colour can vary where the
density does not, at the scales the style asks for.

Each field is white Gaussian noise filtered by a Gaussian of standard deviation ``scale`` times the
grid's longest side (in the frequency domain, so the field wraps around the box: no edge is darker
or flatter than the middle), then scaled to zero mean and unit spread. An orientation other than
``isotropic`` stretches the filter ``NOISE_STRETCH`` times along some axes (``NOISE_ORIENTATIONS``;
the grid's Y is up): ``upright`` fields make strokes that stand upright and ``layers`` fields make
horizontal bands, and both read the same from every view of an orbit around the up axis. Fields
depend on the grid's shape, the scales, the orientations and the seed only, so every frame of a
sequence (and every machine: the CPU generator) sees the same fields in the same place of the box.
"""

from __future__ import annotations

from functools import lru_cache

import torch

NOISE_STRETCH = 4
"""How many times longer an oriented field's structures are along its long axes than across."""
NOISE_ORIENTATIONS = {
    "isotropic": (1, 1, 1),
    "upright": (1, NOISE_STRETCH, 1),
    "layers": (NOISE_STRETCH, 1, NOISE_STRETCH),
}
"""Per orientation, how many times ``scale`` the filter's standard deviation is along (Z, Y, X)."""


def validate_noise_orientations(orientations) -> tuple[str, ...]:
    """``orientations`` as a tuple of distinct names of ``NOISE_ORIENTATIONS``."""
    values = tuple(str(name) for name in orientations)
    unknown = [name for name in values if name not in NOISE_ORIENTATIONS]
    if unknown or not values or len(set(values)) != len(values):
        raise ValueError(f"noise orientations must be distinct names of {', '.join(NOISE_ORIENTATIONS)}, got {values}.")
    return values


def validate_noise_scales(scales) -> tuple[float, ...]:
    """``scales`` as a tuple of floats, each in (0, 1] (fractions of the grid's longest side)."""
    values = tuple(float(scale) for scale in scales)
    if not all(0.0 < value <= 1.0 for value in values):
        raise ValueError(f"noise scales must lie in (0, 1] (fractions of the grid's longest side), got {values}.")
    return values


def noise_fields(
    shape: tuple,
    scales: tuple,
    per_scale: int,
    seed: int = 0,
    orientations: tuple = ("isotropic",),
    window: tuple[slice, slice, slice] | None = None,
) -> torch.Tensor:
    """``(len(orientations) * len(scales) * per_scale, Z, Y, X)`` float32 fields on the CPU: per
    orientation in turn, ``per_scale`` in a row at each of ``scales`` (module docstring). The isotropic
    fields are the same whatever other orientations follow. Cached by its arguments: every frame of
    one shape shares them. ``window``: the part of the box to return (a copy of that part only)."""
    shape = tuple(int(n) for n in shape)
    key = (validate_noise_scales(scales), int(per_scale), int(seed), validate_noise_orientations(orientations))
    fields = _noise_fields(shape, *key)
    return (fields if window is None else fields[(slice(None), *window)]).clone()


@lru_cache(maxsize=8)
def _noise_fields(shape: tuple, scales: tuple, per_scale: int, seed: int, orientations: tuple) -> torch.Tensor:
    generator = torch.Generator().manual_seed(seed)
    longest = max(shape)
    # Per axis, the squared frequency in cycles per voxel on the rfft grid.
    frequencies = [torch.fft.fftfreq(n, dtype=torch.float64) for n in shape[:2]] + [
        torch.fft.rfftfreq(shape[2], dtype=torch.float64)
    ]
    squared = [f.view([-1 if axis == a else 1 for a in range(3)]) ** 2 for axis, f in enumerate(frequencies)]
    count = len(scales) * per_scale
    # Filtered into one array and scaled in place: at 256^3 the fields take a gigabyte in float64, and
    # a copy of them (a concatenation, a centred copy, a scaled copy) cost more than the FFTs.
    field = torch.empty((len(orientations) * count,) + shape, dtype=torch.float64)
    # One draw after another: earlier orientations' fields never change.
    for number, orientation in enumerate(orientations):
        white = torch.randn((count,) + shape, generator=generator, dtype=torch.float64)
        spectrum = torch.fft.rfftn(white, dim=(1, 2, 3))
        del white
        stretched = sum(k**2 * f for k, f in zip(NOISE_ORIENTATIONS[orientation], squared, strict=True))
        for index, scale in enumerate(scales):
            sigma = scale * longest  # voxels, across the long axes
            transfer = torch.exp(-2.0 * torch.pi**2 * sigma**2 * stretched)
            part = spectrum[index * per_scale : (index + 1) * per_scale] * transfer
            first = number * count + index * per_scale
            torch.fft.irfftn(part, s=shape, dim=(1, 2, 3), out=field[first : first + per_scale])
    field.sub_(field.mean(dim=(1, 2, 3), keepdim=True))
    field.div_(field.std(dim=(1, 2, 3), keepdim=True).clamp_min(1e-12))
    return field.float()
