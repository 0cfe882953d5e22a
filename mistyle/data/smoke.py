"""An incompressible smoke solver on a MAC grid, in torch: training plumes with their velocity.

One frame (``dt = 1``, lengths in voxels) does, in this order:

1. the inflow: inside a sphere, density is raised to a noisy source value and the velocity is set
   to the plume's inflow velocity;
2. forces: buoyancy ``buoyancy * density`` along +y, and vorticity confinement
   ``epsilon * (N x omega)`` with ``omega = curl u`` and ``N = grad|omega| / |grad|omega||`` (Fedkiw et
   al. 2001), which restores the small swirls that semi-Lagrangian advection smooths away;
3. pressure projection: ``lap p = div u`` with solid walls (zero normal flux) on five sides and an
   open top (``p = 0`` beyond it, so smoke leaves instead of piling up under a lid), solved exactly
   in the cosine bases that diagonalise that Laplacian (DCT-II across x and z, DCT-IV across y),
   then ``u -= grad p`` on the faces, leaving ``div u`` at rounding level;
4. the frame is recorded: the density and the projected velocity at cell centres;
5. semi-Lagrangian advection (trilinear backtrace, clamped at the walls) of density and of the
   face velocities by the projected velocity.

So a recorded frame ``(density_t, velocity_t)`` satisfies ``density_{t+1} ~ warp(density_t,
velocity_t)`` away from the source (``mistyle.warp.warp_grid``): the temporal loss can warp with ``velocity_t``.

Velocities are stored at cell centres, ``(Z, Y, X, 3)``, components in ``(x, y, z)`` order, in
voxels per frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import torch
import torch.nn.functional as F


@dataclass
class PlumeConfig:
    """One plume's physical and inflow parameters (lengths in voxels, time in frames)."""

    resolution: tuple[int, int, int] = (64, 64, 64)  # (Z, Y, X)
    buoyancy: float = 0.08
    vorticity: float = 0.25
    source_position: tuple[float, float, float] = (0.5, 0.12, 0.5)  # (x, y, z) as box fractions
    source_radius: float = 0.08  # fraction of the smallest side
    source_velocity: tuple[float, float, float] = (0.0, 1.0, 0.0)  # (x, y, z), voxels per frame
    source_density: float = 1.0
    source_noise: float = 0.5  # relative amplitude of the inflow's density noise

    @staticmethod
    def random(resolution: tuple[int, int, int], rng: np.random.Generator) -> PlumeConfig:
        """Random inflow position, direction and speed, as the paper randomises its plumes."""
        tilt = rng.uniform(0.0, math.radians(35.0))
        heading = rng.uniform(0.0, 2.0 * math.pi)
        speed = rng.uniform(0.6, 1.6) * min(resolution) / 64.0
        direction = (math.sin(tilt) * math.cos(heading), math.cos(tilt), math.sin(tilt) * math.sin(heading))
        return PlumeConfig(
            resolution=tuple(resolution),
            buoyancy=rng.uniform(0.04, 0.12) * min(resolution) / 64.0,
            vorticity=rng.uniform(0.2, 0.6),
            source_position=(rng.uniform(0.3, 0.7), rng.uniform(0.08, 0.2), rng.uniform(0.3, 0.7)),
            source_radius=rng.uniform(0.06, 0.12),
            source_velocity=tuple(speed * c for c in direction),
        )


@dataclass
class SmokeState:
    density: torch.Tensor  # (Z, Y, X)
    u: torch.Tensor  # (Z, Y, X + 1) x-velocity on x-faces
    v: torch.Tensor  # (Z, Y + 1, X) y-velocity on y-faces
    w: torch.Tensor  # (Z + 1, Y, X) z-velocity on z-faces
    frame: int = 0
    extras: dict = field(default_factory=dict)  # further cell-centred scalars, advected like density


class SmokeSolver:
    """Advance a plume frame by frame; ``step()`` returns the recorded ``(density, velocity)``."""

    def __init__(self, config: PlumeConfig, seed: int = 0, dtype=torch.float32):
        z, y, x = config.resolution
        if min(config.resolution) < 4:
            raise ValueError(f"Smoke needs at least 4 cells per axis, got {config.resolution}.")
        self.config = config
        self.generator = torch.Generator().manual_seed(int(seed))
        zeros = lambda *shape: torch.zeros(shape, dtype=dtype)  # noqa: E731
        self.state = SmokeState(zeros(z, y, x), zeros(z, y, x + 1), zeros(z, y + 1, x), zeros(z + 1, y, x))
        self._poisson = _NeumannPoisson((z, y, x), dtype)
        centres = [torch.arange(n, dtype=dtype) + 0.5 for n in (z, y, x)]
        self._cz, self._cy, self._cx = torch.meshgrid(*centres, indexing="ij")
        sx, sy, sz = config.source_position
        radius = config.source_radius * min(config.resolution)
        distance = torch.sqrt((self._cx - sx * x) ** 2 + (self._cy - sy * y) ** 2 + (self._cz - sz * z) ** 2)
        self._source = (distance <= radius).to(dtype)

    def step(self) -> tuple[np.ndarray, np.ndarray]:
        state = self.state
        self._inflow()
        self._add_forces()
        self._project()
        density = state.density.clone()
        velocity = self.cell_velocity()
        self._advect()
        state.frame += 1
        return density.numpy(), velocity.numpy()

    # ------------------------------------------------------------------ steps
    def _inflow(self):
        state, config = self.state, self.config
        noise = 1.0 + config.source_noise * (2.0 * torch.rand(state.density.shape, generator=self.generator) - 1.0)
        state.density = torch.maximum(state.density, self._source * config.source_density * noise)
        vx, vy, vz = config.source_velocity
        for name, value, dim in (("u", vx, 2), ("v", vy, 1), ("w", vz, 0)):
            mask = _cells_to_faces(self._source, dim) > 0
            setattr(state, name, torch.where(mask, torch.full_like(getattr(state, name), value), getattr(state, name)))

    def _add_forces(self):
        state, config = self.state, self.config
        state.v = state.v + config.buoyancy * _cells_to_faces(self._buoyant(), 1)
        if config.vorticity > 0:
            fx, fy, fz = _vorticity_confinement(self.cell_velocity(), config.vorticity)
            state.u = state.u + _cells_to_faces(fx, 2)
            state.v = state.v + _cells_to_faces(fy, 1)
            state.w = state.w + _cells_to_faces(fz, 0)

    def _project(self):
        state = self.state
        _close_walls(state)
        pressure = self._poisson.solve(self.divergence())
        state.u[:, :, 1:-1] -= pressure[:, :, 1:] - pressure[:, :, :-1]
        state.v[:, 1:-1, :] -= pressure[:, 1:, :] - pressure[:, :-1, :]
        state.v[:, -1, :] += 2.0 * pressure[:, -1, :]  # open top: the ghost cell above holds -p
        state.w[1:-1, :, :] -= pressure[1:, :, :] - pressure[:-1, :, :]

    def _advect(self):
        state = self.state
        z, y, x = state.density.shape
        velocity_at = lambda px, py, pz: (  # noqa: E731
            _sample_faces(state.u, 2, px, py, pz),
            _sample_faces(state.v, 1, px, py, pz),
            _sample_faces(state.w, 0, px, py, pz),
        )
        # Density at cell centres.
        vx, vy, vz = velocity_at(self._cx, self._cy, self._cz)
        back = (self._cx - vx, self._cy - vy, self._cz - vz)
        density = _sample_cells(state.density, *back)
        for name, values in state.extras.items():
            state.extras[name] = _sample_cells(values, *back).clamp_min(0.0)
        # Each velocity component at its own faces.
        new_faces = []
        for name, dim in (("u", 2), ("v", 1), ("w", 0)):
            faces = getattr(state, name)
            px, py, pz = _face_positions(faces.shape, dim, faces.dtype)
            vx, vy, vz = velocity_at(px, py, pz)
            new_faces.append(_sample_faces(faces, dim, px - vx, py - vy, pz - vz))
        state.density = density.clamp_min(0.0)
        state.u, state.v, state.w = new_faces

    def _buoyant(self) -> torch.Tensor:
        """The cell field that buoyancy lifts: smoke density here, temperature for fire."""
        return self.state.density

    # --------------------------------------------------------------- queries
    def divergence(self) -> torch.Tensor:
        """Net outflow of every cell, ``(Z, Y, X)``."""
        s = self.state
        return (s.u[:, :, 1:] - s.u[:, :, :-1]) + (s.v[:, 1:, :] - s.v[:, :-1, :]) + (s.w[1:] - s.w[:-1])

    def cell_velocity(self) -> torch.Tensor:
        """Face velocities averaged to cell centres, ``(Z, Y, X, 3)`` in ``(x, y, z)`` order."""
        s = self.state
        return torch.stack(
            [
                0.5 * (s.u[:, :, 1:] + s.u[:, :, :-1]),
                0.5 * (s.v[:, 1:, :] + s.v[:, :-1, :]),
                0.5 * (s.w[1:] + s.w[:-1]),
            ],
            dim=-1,
        )


# ---------------------------------------------------------------------- helpers
def _close_walls(state: SmokeState) -> None:
    """No flow through the side walls and the floor; the top stays open."""
    state.u[:, :, 0] = state.u[:, :, -1] = 0.0
    state.v[:, 0, :] = 0.0
    state.w[0, :, :] = state.w[-1, :, :] = 0.0


def _cells_to_faces(cells: torch.Tensor, dim: int) -> torch.Tensor:
    """Average cell values onto the faces across ``dim`` (walls take their one neighbour)."""
    padded = torch.cat([cells.narrow(dim, 0, 1), cells, cells.narrow(dim, cells.shape[dim] - 1, 1)], dim=dim)
    return 0.5 * (padded.narrow(dim, 0, cells.shape[dim] + 1) + padded.narrow(dim, 1, cells.shape[dim] + 1))


def _face_positions(shape, dim: int, dtype):
    """Voxel-unit ``(x, y, z)`` positions of the faces across ``dim`` (0=z, 1=y, 2=x)."""
    axes = []
    for axis, n in enumerate(shape):
        axes.append(torch.arange(n, dtype=dtype) + (0.0 if axis == dim else 0.5))
    pz, py, px = torch.meshgrid(*axes, indexing="ij")
    return px, py, pz


def _sample(grid: torch.Tensor, ix: torch.Tensor, iy: torch.Tensor, iz: torch.Tensor) -> torch.Tensor:
    """Trilinear lookup of ``grid (D, H, W)`` at fractional indices, clamped to the grid."""
    d, h, w = grid.shape
    normalise = lambda i, n: 2.0 * i / max(n - 1, 1) - 1.0  # noqa: E731 (align_corners=True: index -> [-1, 1])
    coords = torch.stack([normalise(ix, w), normalise(iy, h), normalise(iz, d)], dim=-1)
    sampled = F.grid_sample(
        grid[None, None], coords.reshape(1, -1, 1, 1, 3), mode="bilinear", padding_mode="border", align_corners=True
    )
    return sampled.reshape(ix.shape)


def _sample_cells(cells, px, py, pz):
    """Cell-centred field at voxel-unit positions."""
    return _sample(cells, px - 0.5, py - 0.5, pz - 0.5)


def _sample_faces(faces, dim: int, px, py, pz):
    """Face-centred field (faces across ``dim``) at voxel-unit positions."""
    shift = [0.5, 0.5, 0.5]
    shift[2 - dim] = 0.0  # (x, y, z) order: dim 2 is x
    return _sample(faces, px - shift[0], py - shift[1], pz - shift[2])


def _vorticity_confinement(velocity: torch.Tensor, epsilon: float):
    """Confinement force ``epsilon (N x omega)`` at cell centres, each ``(Z, Y, X)``."""
    vx, vy, vz = velocity.unbind(-1)

    def d(field, axis):  # central difference along x (2), y (1) or z (0)
        return torch.gradient(field, dim=axis)[0]

    wx = d(vz, 1) - d(vy, 0)
    wy = d(vx, 0) - d(vz, 2)
    wz = d(vy, 2) - d(vx, 1)
    magnitude = torch.sqrt(wx**2 + wy**2 + wz**2)
    nx, ny, nz = d(magnitude, 2), d(magnitude, 1), d(magnitude, 0)
    norm = torch.sqrt(nx**2 + ny**2 + nz**2) + 1e-6
    nx, ny, nz = nx / norm, ny / norm, nz / norm
    return epsilon * (ny * wz - nz * wy), epsilon * (nz * wx - nx * wz), epsilon * (nx * wy - ny * wx)


class _NeumannPoisson:
    """Exact solver of ``lap p = rhs`` on cells: Neumann walls, except Dirichlet (p = 0) above the top.

    Each axis has an orthonormal cosine basis that diagonalises its 1D Laplacian: DCT-II
    (``cos(pi k (i + 1/2) / n)``, eigenvalue ``2 cos(pi k / n) - 2``) for Neumann-Neumann, and DCT-IV
    (``cos(pi (k + 1/2)(i + 1/2) / n)``, eigenvalue ``2 cos(pi (k + 1/2) / n) - 2``) for y, Neumann at
    the floor and Dirichlet at the top. The open top also removes the null space.
    """

    def __init__(self, shape, dtype):
        z, y, x = shape
        bases = [self._basis(z, 0.0), self._basis(y, 0.5), self._basis(x, 0.0)]
        eigen = [
            2.0 * torch.cos(math.pi * (torch.arange(n, dtype=torch.float64) + shift) / n) - 2.0
            for n, shift in ((z, 0.0), (y, 0.5), (x, 0.0))
        ]
        total = eigen[0][:, None, None] + eigen[1][None, :, None] + eigen[2][None, None, :]
        self.inverse_eigen = (1.0 / total).to(dtype)
        self.bases = [b.to(dtype) for b in bases]

    @staticmethod
    def _basis(n: int, shift: float) -> torch.Tensor:
        k = torch.arange(n, dtype=torch.float64)[:, None] + shift
        i = torch.arange(n, dtype=torch.float64)[None, :]
        matrix = torch.cos(math.pi * k * (i + 0.5) / n) * math.sqrt(2.0 / n)
        if shift == 0.0:
            matrix[0] /= math.sqrt(2.0)
        return matrix  # orthonormal: the inverse is the transpose

    def solve(self, rhs: torch.Tensor) -> torch.Tensor:
        cz, cy, cx = self.bases
        spectrum = self._transform(rhs, cz, cy, cx) * self.inverse_eigen
        return self._transform(spectrum, cz.T, cy.T, cx.T)

    @staticmethod
    def _transform(volume, mz, my, mx):
        """Apply a matrix along each axis: one matrix product per axis."""
        volume = volume @ mx.T  # x
        volume = (volume.transpose(1, 2) @ my.T).transpose(1, 2)  # y
        return (volume.permute(1, 2, 0) @ mz.T).permute(2, 0, 1)  # z


@dataclass
class FireConfig(PlumeConfig):
    """A burning plume: hot fuel enters, burns while above ignition, heats, cools, leaves soot."""

    buoyancy: float = 0.12  # per unit temperature
    source_velocity: tuple[float, float, float] = (0.0, 0.8, 0.0)
    burn_rate: float = 0.3  # fraction of the fuel burned per frame above ignition
    ignition: float = 0.2
    heat: float = 2.0  # temperature released per unit fuel burned
    cooling: float = 0.15  # fraction of the temperature lost per frame
    soot: float = 0.2  # smoke density left per unit fuel burned


class FireSolver(SmokeSolver):
    """Fuel and temperature on top of the smoke solver; ``step()`` records the flame.

    The recorded ``density`` is the flame, ``1 - exp(-temperature)`` in [0, 1): hot gas, the part of
    a fire that glows and that the paper stylizes (its Fig. 19). ``state.density`` is the soot.
    """

    def __init__(self, config: FireConfig, seed: int = 0, dtype=torch.float32):
        super().__init__(config, seed, dtype)
        self.state.extras = {
            "fuel": torch.zeros_like(self.state.density),
            "temperature": torch.zeros_like(self.state.density),
        }

    def step(self) -> tuple[np.ndarray, np.ndarray]:
        state = self.state
        self._inflow()
        self._burn()
        self._add_forces()
        self._project()
        flame = 1.0 - torch.exp(-state.extras["temperature"])
        velocity = self.cell_velocity()
        self._advect()
        state.frame += 1
        return flame.numpy(), velocity.numpy()

    def _inflow(self):
        super()._inflow()
        fuel = self._source * (
            1.0 + self.config.source_noise * (2.0 * torch.rand(self._source.shape, generator=self.generator) - 1.0)
        )
        self.state.extras["fuel"] = torch.maximum(self.state.extras["fuel"], fuel)
        self.state.extras["temperature"] = torch.maximum(self.state.extras["temperature"], self._source * 0.5)
        self.state.density = self.state.density * (1.0 - self._source)  # the inflow itself carries no soot

    def _burn(self):
        config, extras = self.config, self.state.extras
        burned = config.burn_rate * extras["fuel"] * (extras["temperature"] > config.ignition)
        extras["fuel"] = extras["fuel"] - burned
        extras["temperature"] = (extras["temperature"] + config.heat * burned) * (1.0 - config.cooling)
        self.state.density = self.state.density + config.soot * burned

    def _buoyant(self) -> torch.Tensor:
        return self.state.extras["temperature"]


def simulate(config: PlumeConfig, frames: int, seed: int = 0):
    """Yield ``(frame, density (Z,Y,X) float32, velocity (Z,Y,X,3) float32)`` for ``frames`` frames.

    A ``FireConfig`` runs the fire solver, whose ``density`` is the flame.
    """
    solver = (FireSolver if isinstance(config, FireConfig) else SmokeSolver)(config, seed=seed)
    for frame in range(frames):
        density, velocity = solver.step()
        yield frame, density, velocity
