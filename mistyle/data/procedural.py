"""Procedural densities: quick, varied, deterministic shapes for tests, examples and validation.

A pyroclastic sphere displaces the distance field of a sphere by fractal noise (the classic
production cloud/explosion primitive): density = clamp((R + A * fbm(p) - |p|) / falloff, 0, 1).
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F


def fractal_noise(shape_zyx: tuple[int, int, int], octaves: int = 4, base_cells: int = 4, seed: int = 0) -> np.ndarray:
    """Fractal value noise in about [-1, 1], shape ``(Z, Y, X)`` float32.

    Each octave is a random lattice of ``base_cells * 2**o`` cells upsampled trilinearly to the
    grid; octave amplitudes halve.
    """
    generator = torch.Generator().manual_seed(seed)
    total = torch.zeros(shape_zyx, dtype=torch.float32)
    amplitude, norm = 1.0, 0.0
    for octave in range(octaves):
        cells = base_cells * 2**octave
        lattice = torch.rand((1, 1, cells + 1, cells + 1, cells + 1), generator=generator) * 2 - 1
        total += amplitude * F.interpolate(lattice, size=shape_zyx, mode="trilinear", align_corners=True)[0, 0]
        norm += amplitude
        amplitude *= 0.5
    return (total / norm).numpy()


def pyroclastic_sphere(
    shape_zyx: tuple[int, int, int] = (64, 64, 64),
    radius: float = 0.36,
    amplitude: float = 0.12,
    falloff: float = 0.04,
    seed: int = 0,
) -> np.ndarray:
    """A noise-displaced sphere centred in the unit-longest-side box; ``(Z, Y, X)`` in [0, 1]."""
    from ..scenes.box import MediumBox

    positions = MediumBox(shape_zyx).voxel_centres()
    distance = np.linalg.norm(positions, axis=-1)
    noise = fractal_noise(shape_zyx, seed=seed)
    return np.clip((radius + amplitude * noise - distance) / falloff, 0.0, 1.0).astype(np.float32)


def colour_noise_albedo(shape_zyx: tuple[int, int, int], seed: int = 0) -> np.ndarray:
    """A colourful, low-frequency RGB albedo ``(Z, Y, X, 3)`` in [0.15, 0.95] (a stand-in style)."""
    channels = [fractal_noise(shape_zyx, octaves=2, base_cells=3, seed=seed + c) for c in range(3)]
    return (0.55 + 0.4 * np.clip(np.stack(channels, axis=-1) * 1.5, -1.0, 1.0)).astype(np.float32)
