"""A density prepared for the fast layer: validated grid, extinction scale and its Ls grid."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..conventions import DEFAULT_DENSITY_SCALE, LS_DIRECTIONS
from ..scenes.box import MediumBox
from ..scenes.medium import validate_density_scale
from ..volume import validate_density


@dataclass(frozen=True, eq=False)
class PreparedDensity:
    """Everything about one density that the layer needs and that does not depend on the albedo.

    Attributes:
        density: ``(Z, Y, X)`` float32, unitless, >= 0.
        density_scale: ``sigma_t = density_scale * density`` in 1/world-length (box side 1).
        ls: ``(Z, Y, X) * f`` float32 nodal values of the in-scattered radiance for unit environment
            radiance (``prepare_density`` fits them to the Ls samples), on the density's grid
            (``f = 1``) or on one ``f`` times finer (``ls_grid_factor``).
        directions: K used for ``ls``.
    """

    density: np.ndarray
    density_scale: float
    ls: np.ndarray
    directions: int = LS_DIRECTIONS

    def __post_init__(self):
        _ls_grid_factor(self.ls.shape, self.density.shape)

    @property
    def ls_grid_factor(self) -> int:
        """How many times finer than the density's the Ls grid is (1: the same grid, as in the paper)."""
        return _ls_grid_factor(self.ls.shape, self.density.shape)

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(self.density.shape)

    @property
    def box(self) -> MediumBox:
        return MediumBox(self.shape)

    @functools.cached_property
    def march_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World corners ``(min, max)`` of the part of the box where the extinction can be non-zero
        (``MediumBox.field_support``): the layer marches only there."""
        return self.box.field_support(self.density > 0)

    @property
    def sigma_t(self) -> np.ndarray:
        return (self.density * np.float32(self.density_scale)).astype(np.float32)


def prepare_density(
    density,
    density_scale: float = DEFAULT_DENSITY_SCALE,
    directions: int = LS_DIRECTIONS,
    method: str = "sheared",
    ls: np.ndarray | None = None,
    ls_grid_factor: int = 1,
) -> PreparedDensity:
    """Validate ``density`` and precompute its Ls grid (or adopt a cached ``ls``).

    Args:
        density: ``(Z, Y, X)`` array, finite and >= 0.
        density_scale: extinction per unit density, 1/world-length.
        directions: K Hammersley directions for Ls.
        method: ``"sheared"`` or ``"bruteforce"`` (see ``inscatter``).
        ls: Ls samples previously computed for this density and scale by ``inscattered_radiance``
            (e.g. from a dataset cache), instead of computing them.
        ls_grid_factor: compute Ls on a grid this many times finer (``inscatter.inscattered_radiance``).
            3 puts fine voxel centres on the density's own, so the resampled extinction is exactly the
            rendered field; for about 35x the precompute time and 27x its memory (docs/performance.md).

    The layer interpolates ``PreparedDensity.ls`` trilinearly, so it holds the nodal values that fit
    the Ls samples best (``inscatter.trilinear_nodes``), not the samples themselves: point samples
    would overestimate Ls inside the medium's surface (docs/performance.md).
    """
    from ..backend import active_variant

    grid = validate_density(density)
    scale = validate_density_scale(density_scale)
    sigma_t = grid * np.float32(scale)
    active_variant()
    from .inscatter import (
        inscattered_radiance,
        layer_reads_ls,
        resample_trilinear,
        trilinear_nodes,
    )

    if ls is None:
        ls = inscattered_radiance(sigma_t, directions=directions, method=method, grid_factor=ls_grid_factor)
    ls = np.asarray(ls, dtype=np.float32)
    factor = _ls_grid_factor(ls.shape, grid.shape)
    fine_sigma_t = sigma_t if factor == 1 else resample_trilinear(sigma_t, factor)
    nodes = trilinear_nodes(ls, valid=layer_reads_ls(fine_sigma_t))
    return PreparedDensity(density=grid, density_scale=scale, ls=np.ascontiguousarray(nodes), directions=directions)


def _ls_grid_factor(ls_shape, density_shape) -> int:
    """How many times finer than ``density_shape`` the Ls grid ``ls_shape`` is; ``ValueError`` unless whole."""
    ls_shape, density_shape = tuple(ls_shape), tuple(density_shape)
    factor = ls_shape[0] // density_shape[0] if len(ls_shape) == 3 else 0
    if factor < 1 or ls_shape != tuple(factor * n for n in density_shape):
        raise ValueError(f"Ls grid {ls_shape} is neither the density grid {density_shape} nor a whole multiple of it.")
    return factor
