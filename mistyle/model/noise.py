"""Smooth noise fields fixed in a grid's box: the SKPN's noise inputs.

The density alone decides where the SKPN's features vary, so without another input every style's
colours follow the density's arrangement (``docs/decisions/2026-12-02-noise-site.md``). The noise site
adds, before the decoder's tanh, a style-weighted sum of these fields: colour can vary where the
density does not, at the scales the style asks for.

Each field is white Gaussian noise filtered by a Gaussian of standard deviation ``scale`` times the
grid's longest side (in the frequency domain, so the field wraps around the box: no edge is darker
or flatter than the middle), then scaled to zero mean and unit spread. Fields depend on the grid's
shape, the scales and the seed only, so every frame of a sequence (and every machine: the CPU
generator) sees the same fields in the same place of the box.
"""

from __future__ import annotations

from functools import lru_cache

import torch


def validate_noise_scales(scales) -> tuple[float, ...]:
    """``scales`` as a tuple of floats, each in (0, 1] (fractions of the grid's longest side)."""
    values = tuple(float(scale) for scale in scales)
    if not all(0.0 < value <= 1.0 for value in values):
        raise ValueError(f"noise scales must lie in (0, 1] (fractions of the grid's longest side), got {values}.")
    return values


def noise_fields(shape: tuple, scales: tuple, per_scale: int, seed: int = 0) -> torch.Tensor:
    """``(len(scales) * per_scale, Z, Y, X)`` float32 fields on the CPU, ``per_scale`` in a row at each of
    ``scales`` (module docstring). Cached by its arguments: every frame of one shape shares them."""
    return _noise_fields(tuple(int(n) for n in shape), validate_noise_scales(scales), int(per_scale), int(seed)).clone()


@lru_cache(maxsize=8)
def _noise_fields(shape: tuple, scales: tuple, per_scale: int, seed: int) -> torch.Tensor:
    generator = torch.Generator().manual_seed(seed)
    white = torch.randn((len(scales) * per_scale,) + shape, generator=generator, dtype=torch.float64)
    spectrum = torch.fft.rfftn(white, dim=(1, 2, 3))
    longest = max(shape)
    # Squared frequency in cycles per voxel on the rfft grid.
    frequencies = [torch.fft.fftfreq(n, dtype=torch.float64) for n in shape[:2]] + [
        torch.fft.rfftfreq(shape[2], dtype=torch.float64)
    ]
    squared = sum(f.view([-1 if axis == a else 1 for a in range(3)]) ** 2 for axis, f in enumerate(frequencies))
    fields = []
    for index, scale in enumerate(scales):
        sigma = scale * longest  # voxels
        transfer = torch.exp(-2.0 * torch.pi**2 * sigma**2 * squared)
        part = spectrum[index * per_scale : (index + 1) * per_scale] * transfer
        fields.append(torch.fft.irfftn(part, s=shape, dim=(1, 2, 3)))
    field = torch.cat(fields)
    field = field - field.mean(dim=(1, 2, 3), keepdim=True)
    field = field / field.std(dim=(1, 2, 3), keepdim=True).clamp_min(1e-12)
    return field.float()
