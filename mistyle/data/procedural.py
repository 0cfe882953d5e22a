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


def sphere_sdf(shape_zyx: tuple[int, int, int], radius: float = 0.35) -> np.ndarray:
    """Signed distance (box units, negative inside) to a sphere at the box centre, ``(Z, Y, X)``."""
    from ..scenes.box import MediumBox

    return (np.linalg.norm(MediumBox(shape_zyx).voxel_centres(), axis=-1) - radius).astype(np.float32)


def torus_sdf(shape_zyx: tuple[int, int, int], major: float = 0.3, minor: float = 0.12) -> np.ndarray:
    """Signed distance to a torus around the y axis at the box centre, ``(Z, Y, X)``."""
    from ..scenes.box import MediumBox

    p = MediumBox(shape_zyx).voxel_centres()
    ring = np.sqrt(p[..., 0] ** 2 + p[..., 2] ** 2) - major
    return (np.sqrt(ring**2 + p[..., 1] ** 2) - minor).astype(np.float32)


def noise_filled_level_set(
    sdf: np.ndarray, falloff: float = 0.03, seed: int = 0, octaves: int = 4, base_cells: int = 6, gain: float = 1.5
) -> np.ndarray:
    """Fill the inside of a level set (``sdf < 0``) with fractal noise; ``(Z, Y, X)`` in [0, 1].

    The boundary fades over ``falloff`` (box units) so the shape stays recognisable, while the
    noise makes the inside wispy: ``clamp(-sdf / falloff, 0, 1) * clamp(1/2 + gain * fbm, 0, 1)``.
    """
    edge = np.clip(-np.asarray(sdf, dtype=np.float32) / falloff, 0.0, 1.0)
    noise = fractal_noise(sdf.shape, octaves=octaves, base_cells=base_cells, seed=seed)
    return (edge * np.clip(0.5 + gain * noise, 0.0, 1.0)).astype(np.float32)


def spot_noise(
    vertices: np.ndarray,
    faces: np.ndarray,
    resolution: int = 64,
    impulses: int = 2000,
    tangent_size: float = 0.04,
    normal_size: float = 0.012,
    depth: float = 0.03,
    margin: float = 0.1,
    seed: int = 0,
) -> np.ndarray:
    """Volumetric spot noise in a shell around a mesh surface; ``(Z, Y, X)`` in [0, 1].

    Impulses are placed on the surface with probability proportional to triangle area, pushed
    inward along the normal by up to ``depth``, and each contributes an anisotropic Gaussian
    kernel ``a exp(-1/2 (x - x0)^T Sigma^-1 (x - x0))`` with ``Sigma = R S S^T R^T``: ``R`` the
    surface frame with a random rotation about the normal, ``S = diag(t, t', normal_size)`` with
    tangent scales up to ``tangent_size``. Flat, surface-aligned spots give a shell texture.
    """
    from .mesh import fit_to_box

    rng = np.random.default_rng(seed)
    placed, box = fit_to_box(np.asarray(vertices, dtype=np.float64), resolution, margin)
    faces = np.asarray(faces, dtype=np.int64)
    a, b, c = placed[faces[:, 0]], placed[faces[:, 1]], placed[faces[:, 2]]
    cross = np.cross(b - a, c - a)
    area = np.linalg.norm(cross, axis=1)
    if area.sum() <= 0:
        raise ValueError("The mesh has no surface area to place spots on.")
    chosen = rng.choice(len(faces), size=impulses, p=area / area.sum())
    u, v = rng.random(impulses), rng.random(impulses)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    normal = cross[chosen] / area[chosen, None]
    centre = a[chosen] + u[:, None] * (b - a)[chosen] + v[:, None] * (c - a)[chosen]
    centre -= normal * (depth * rng.random(impulses))[:, None]
    # Surface frame: tangent from the triangle's first edge, rotated by a random angle.
    tangent = (b - a)[chosen]
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    bitangent = np.cross(normal, tangent)
    angle = rng.uniform(0, 2 * np.pi, impulses)[:, None]
    t1 = np.cos(angle) * tangent + np.sin(angle) * bitangent
    t2 = np.cross(normal, t1)
    scales = np.stack(
        [
            tangent_size * rng.uniform(0.5, 1.0, impulses),
            tangent_size * rng.uniform(0.2, 0.6, impulses),
            np.full(impulses, normal_size),
        ],
        axis=1,
    )
    frames = np.stack([t1, t2, normal], axis=2)  # columns: the kernel's axes
    amplitude = rng.uniform(0.5, 1.0, impulses)

    density = torch.zeros(int(np.prod(box.shape_zyx)), dtype=torch.float32)
    reach = int(np.ceil(3 * tangent_size / box.voxel_size))
    offsets = np.stack(np.meshgrid(*(np.arange(-reach, reach + 1),) * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    res_xyz = np.array(box.resolution_xyz, dtype=np.int64)
    for chunk in np.array_split(np.arange(impulses), max(1, impulses // 256)):
        nearest = np.floor((centre[chunk] - box.bbox_min) / box.voxel_size).astype(np.int64)  # (n, 3) xyz
        voxels = nearest[:, None, :] + offsets[None, :, ::-1]  # offsets are (z,y,x); use xyz
        inside = np.all((voxels >= 0) & (voxels < res_xyz), axis=-1)
        points = box.bbox_min + (voxels + 0.5) * box.voxel_size
        local = np.einsum(
            "nkij,nki->nkj",
            np.broadcast_to(frames[chunk, None], points.shape[:2] + (3, 3)),
            points - centre[chunk, None],
        )
        exponent = -0.5 * np.sum((local / scales[chunk, None]) ** 2, axis=-1)
        values = amplitude[chunk, None] * np.exp(exponent) * inside
        flat = (voxels[..., 2] * res_xyz[1] + voxels[..., 1]) * res_xyz[0] + voxels[..., 0]
        density.index_add_(
            0, torch.from_numpy(np.where(inside, flat, 0).ravel()), torch.from_numpy(values.ravel().astype(np.float32))
        )
    density = density.reshape(box.shape_zyx).numpy()
    return np.clip(density / max(float(np.percentile(density[density > 0], 99)), 1e-6), 0.0, 1.0).astype(np.float32)
