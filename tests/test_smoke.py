"""The smoke solver: incompressibility, the Poisson solve, mass, saved velocity, determinism."""

import numpy as np
import pytest
import torch

from mistyle.data.smoke import PlumeConfig, SmokeSolver, _NeumannPoisson, simulate
from mistyle.warp import warp_grid as warp

RES = (20, 24, 16)


def run_frames(frames, seed=0, config=None):
    return list(simulate(config or PlumeConfig(resolution=RES), frames, seed=seed))


def test_projection_leaves_velocity_divergence_free():
    solver = SmokeSolver(PlumeConfig(resolution=RES), seed=1)
    for _ in range(15):
        solver.step()
    solver._inflow()
    solver._add_forces()
    before = float(solver.divergence().abs().max())
    solver._project()
    after = float(solver.divergence().abs().max())
    assert before > 1e-2
    assert after < 1e-4


def test_poisson_solver_inverts_the_discrete_laplacian():
    """Neumann walls and floor, p = 0 above the top: L(solve(rhs)) == rhs."""
    shape = (6, 7, 5)
    rhs = torch.randn(shape, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    p = _NeumannPoisson(shape, torch.float64).solve(rhs)
    padded = torch.nn.functional.pad(p[None, None], (1, 1, 1, 1, 1, 1), mode="replicate")[0, 0]
    padded[1:-1, -1, 1:-1] = -p[:, -1, :]  # Dirichlet ghost above the top
    lap = -6 * p
    for axis in range(3):
        for offset in (0, 2):
            index = [slice(1, -1)] * 3
            index[axis] = slice(offset, offset + shape[axis])
            lap = lap + padded[tuple(index)]
    torch.testing.assert_close(lap, rhs, atol=1e-9, rtol=1e-9)


def test_advection_roughly_conserves_mass_in_a_closed_region():
    """A blob carried by a divergence-free swirl, far from the walls and the source."""
    solver = SmokeSolver(PlumeConfig(resolution=(32, 32, 32), source_density=0.0, buoyancy=0.0, vorticity=0.0))
    state = solver.state
    c = (solver._cx - 16) ** 2 + (solver._cy - 16) ** 2 + (solver._cz - 16) ** 2
    state.density = torch.exp(-c / 20.0)
    # Rotation about the z axis (divergence-free), at face positions.
    from mistyle.data.smoke import _face_positions

    px, py, _ = _face_positions(state.u.shape, 2, torch.float32)
    state.u = -0.05 * (py - 16)
    px, py, _ = _face_positions(state.v.shape, 1, torch.float32)
    state.v = 0.05 * (px - 16)
    mass = float(state.density.sum())
    for _ in range(10):
        solver._project()
        solver._advect()
    # Semi-Lagrangian advection is not conservative; 10 frames of a 0.8 voxel/frame swirl lose ~3%.
    assert abs(float(state.density.sum()) / mass - 1) < 0.05


def test_saved_velocity_moves_the_density():
    """Warping frame t by its velocity predicts frame t+1 at least 10x better than no warp."""
    frames = run_frames(30, seed=2)
    source = SmokeSolver(PlumeConfig(resolution=RES))._source.numpy() > 0
    outside = ~source
    for t in (20, 25):
        _, density, velocity = frames[t]
        _, following, _ = frames[t + 1]
        warped_error = np.abs(warp(density, velocity) - following)[outside].mean()
        still_error = np.abs(density - following)[outside].mean()
        assert still_error > 0
        assert warped_error < 0.1 * still_error


def test_simulation_is_deterministic_per_seed():
    first, second, other = run_frames(8, seed=5), run_frames(8, seed=5), run_frames(8, seed=6)
    for (_, d1, v1), (_, d2, v2) in zip(first, second):
        np.testing.assert_array_equal(d1, d2)
        np.testing.assert_array_equal(v1, v2)
    assert not np.array_equal(first[-1][1], other[-1][1])


def test_frames_have_the_documented_layout():
    _, density, velocity = run_frames(3)[-1]
    assert density.shape == RES and density.dtype == np.float32 and density.min() >= 0
    assert velocity.shape == RES + (3,) and velocity.dtype == np.float32
    # The plume rises: mean y-velocity over the smoke is positive (component 1 is y).
    assert velocity[..., 1][density > 0.1].mean() > 0


def test_random_plumes_differ_and_stay_in_range():
    rng = np.random.default_rng(0)
    configs = [PlumeConfig.random((64, 64, 64), rng) for _ in range(5)]
    assert len({c.source_position for c in configs}) == 5
    for config in configs:
        assert all(0 < s < 1 for s in config.source_position)
        assert config.source_velocity[1] > 0


def test_tiny_grids_are_refused():
    with pytest.raises(ValueError, match="at least 4"):
        SmokeSolver(PlumeConfig(resolution=(3, 8, 8)))


def test_fire_burns_rises_and_cools():
    from mistyle.data.smoke import FireConfig, FireSolver

    solver = FireSolver(FireConfig(resolution=(24, 32, 24), source_radius=0.15), seed=0)
    for _ in range(25):
        flame, velocity = solver.step()
    assert 0 <= flame.min() and flame.max() < 1
    assert float(solver.state.extras["fuel"].sum()) > 0 and float(solver.state.density.sum()) > 0  # soot
    profile = flame.mean(axis=(0, 2))  # by height y
    peak = int(profile.argmax())
    assert profile[peak:].max() == profile[peak] and profile[-1] < 0.8 * profile[peak]  # cools as it rises
    assert velocity[..., 1][flame > 0.3].mean() > 0  # hot gas rises
    solver._inflow(), solver._burn(), solver._add_forces(), solver._project()
    assert float(solver.divergence().abs().max()) < 1e-4
