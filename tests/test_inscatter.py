"""Ls precompute: analytic homogeneous cases, zero-component directions, sheared vs brute force."""

import numpy as np
import pytest

from mistyle.integrators import inscatter
from mistyle.integrators.inscatter import hammersley_sphere, inscattered_radiance
from mistyle.scenes import MediumBox


def analytic_homogeneous_ls(box: MediumBox, sigma: float, omegas: np.ndarray) -> np.ndarray:
    """mean_k exp(-sigma * distance from each voxel centre to the box along omega_k)."""
    p = box.voxel_centres()[..., None, :]  # (Z, Y, X, 1, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(omegas > 0, (box.bbox_max - p) / omegas, np.where(omegas < 0, (box.bbox_min - p) / omegas, np.inf))
    return np.exp(-sigma * t.min(axis=-1)).mean(axis=-1)


def test_hammersley_directions_are_unit_balanced_and_antipodal():
    omegas = hammersley_sphere(128)
    np.testing.assert_allclose(np.linalg.norm(omegas, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(omegas[64:], -omegas[:64])
    assert np.abs(omegas.mean(axis=0)).max() < 1e-12
    assert len(np.unique(omegas.round(8), axis=0)) == 128
    # Equal-area stratified: each eighth of the sphere's z range holds an eighth of the points.
    counts, _ = np.histogram(omegas[:, 2], bins=8, range=(-1, 1))
    assert np.all(counts == 16)
    with pytest.raises(ValueError, match="even"):
        hammersley_sphere(7)


@pytest.mark.parametrize("method", ["sheared", "bruteforce"])
def test_empty_medium_sees_the_whole_environment(mi, method):
    ls = inscattered_radiance(np.zeros((6, 7, 8), np.float32), directions=16, method=method, only_where_used=False)
    np.testing.assert_allclose(ls, 1.0, atol=1e-6)


@pytest.mark.parametrize("method,tol", [("bruteforce", 2e-5), ("sheared", 2e-3)])
def test_homogeneous_cube_matches_analytic(mi, method, tol):
    shape, sigma = (12, 10, 14), 3.0
    ls = inscattered_radiance(np.full(shape, sigma, np.float32), directions=32, method=method)
    expected = analytic_homogeneous_ls(MediumBox(shape), sigma, hammersley_sphere(32))
    assert np.abs(ls - expected).max() < tol


@pytest.mark.parametrize("method", ["sheared", "bruteforce"])
def test_axis_aligned_directions_do_not_produce_nan(mi, method):
    """Directions with zero components (a naive slab distance divides 0 by 0) stay finite."""
    import mitsuba as mi_module

    shape, sigma = (8, 9, 10), 2.0
    box = MediumBox(shape)
    primaries = np.concatenate([np.eye(3), [[0.0, 0.6, 0.8]]])
    omegas = np.concatenate([primaries, -primaries])
    texture = mi_module.Texture3f(mi_module.TensorXf(np.full(shape + (1,), sigma, np.float32)))
    every_voxel = inscatter._voxel_centre_positions(np.ones(shape, dtype=bool))
    if method == "sheared":  # takes one direction of each antipodal pair
        ls = inscatter._sheared(texture, box, every_voxel, primaries)
    else:
        ls = inscatter._bruteforce(texture, box, every_voxel, omegas, steps=16)
    ls = np.asarray(ls).reshape(shape)
    assert np.all(np.isfinite(ls))
    np.testing.assert_allclose(ls, analytic_homogeneous_ls(box, sigma, omegas), atol=2e-3)


def test_sheared_matches_bruteforce_on_a_heterogeneous_blob(mi, blob_density):
    sigma_t = 25.0 * blob_density
    fast = inscattered_radiance(sigma_t, directions=64, method="sheared")
    reference = inscattered_radiance(sigma_t, directions=64, method="bruteforce", steps=128)
    rel_rmse = np.sqrt(np.mean((fast - reference) ** 2) / np.mean(reference**2))
    assert rel_rmse < 1e-2  # a bilinear-between-lines sweep gives ~5% on this coarse, sharp blob
    assert fast.min() < 0.5  # the blob really shadows itself


def test_unknown_method_is_rejected(mi):
    with pytest.raises(ValueError, match="Unknown Ls method"):
        inscattered_radiance(np.zeros((4, 4, 4), np.float32), method="magic")


def test_ls_is_only_computed_where_the_layer_uses_it(mi, blob_density):
    """Skipping voxels far from any density changes no layer image, and only those voxels."""
    import torch

    from mistyle.bridge_torch import render_views
    from mistyle.integrators import PreparedDensity
    from mistyle.scenes import CameraPath

    sigma_t = 25.0 * blob_density
    dense = inscattered_radiance(sigma_t, directions=32, only_where_used=False)
    sparse = inscattered_radiance(sigma_t, directions=32)
    used = inscatter.layer_reads_ls(sigma_t)
    assert 0 < used.sum() < used.size
    np.testing.assert_allclose(sparse[used], dense[used], rtol=1e-6)
    assert np.all(sparse[~used] == 1.0)
    views, albedo = CameraPath().turntable(2), torch.rand((3,) + blob_density.shape)
    images = [render_views(albedo, PreparedDensity(blob_density, 25.0, ls), views, 16) for ls in (dense, sparse)]
    torch.testing.assert_close(images[0], images[1], rtol=0, atol=0)


@pytest.mark.slow
def test_sheared_ls_changes_layer_images_by_under_half_a_percent_at_64(mi):
    """The issue's bar, at its size: 64^3, K=128, 4 views at 160^2, against brute-force Ls."""
    import torch

    from mistyle.bridge_torch import render_views
    from mistyle.data.procedural import pyroclastic_sphere
    from mistyle.integrators import prepare_density
    from mistyle.scenes import CameraPath

    density = pyroclastic_sphere((64, 64, 64), seed=1)
    fast = prepare_density(density, 20.0, 128, method="sheared")
    brute = prepare_density(density, 20.0, 128, method="bruteforce")
    albedo = torch.rand((3, 64, 64, 64), generator=torch.Generator().manual_seed(0))
    views = CameraPath().turntable(4, offset=0.1)
    image_fast, image_brute = (render_views(albedo, p, views, 160) for p in (fast, brute))
    rel_rmse = float(((image_fast - image_brute).pow(2).mean() / image_brute.pow(2).mean()).sqrt())
    assert rel_rmse < 5e-3


def test_resampling_keeps_the_trilinear_field(mi):
    from mistyle.integrators.inscatter import resample_trilinear

    z, y, x = np.meshgrid(*(np.arange(n, dtype=np.float32) for n in (6, 5, 4)), indexing="ij")
    ramp = 0.5 + 0.1 * x + 0.2 * y - 0.05 * z
    fine = resample_trilinear(ramp, 2)
    assert fine.shape == (12, 10, 8)
    # Fine centre j sits at (j + 0.5) / 2 - 0.5 coarse voxels: the ramp exactly, clamped beyond the end centres.
    fz, fy, fx = (np.clip((np.arange(n) + 0.5) / 2 - 0.5, 0, n // 2 - 1) for n in (12, 10, 8))
    expected = 0.5 + 0.1 * fx[None, None] + 0.2 * fy[None, :, None] - 0.05 * fz[:, None, None]
    np.testing.assert_allclose(fine, expected, atol=1e-5)


def test_ls_on_a_finer_grid_agrees_with_the_density_grid(mi, blob_density):
    sigma_t = blob_density * np.float32(6.0)
    coarse = inscattered_radiance(sigma_t, 32, "sheared")
    fine = inscattered_radiance(sigma_t, 32, "sheared", grid_factor=2)
    assert fine.shape == tuple(2 * n for n in sigma_t.shape)
    # The mean of each 2x2x2 block of fine values is close to the coarse value at its centre, inside the medium.
    blocks = fine.reshape(sigma_t.shape[0], 2, sigma_t.shape[1], 2, sigma_t.shape[2], 2).mean(axis=(1, 3, 5))
    inside = sigma_t > 1.0
    assert np.abs(blocks - coarse)[inside].max() < 0.03
    with pytest.raises(ValueError, match="grid_factor"):
        inscattered_radiance(sigma_t, 32, "sheared", grid_factor=1.5)


def test_trilinear_nodes_keep_linear_fields_and_fit_a_convex_one_better():
    from mistyle.integrators.inscatter import trilinear_nodes

    z, y, x = np.meshgrid(*(np.arange(n, dtype=np.float64) for n in (9, 10, 11)), indexing="ij")
    ramp = 0.2 + 0.03 * x - 0.02 * y + 0.01 * z
    inner = (
        slice(3, -3),
    ) * 3  # the outer nodes also fit the ramp's rise past the outer centres, which the texture clamps
    np.testing.assert_allclose(trilinear_nodes(ramp)[inner], ramp[inner], atol=1e-4)
    np.testing.assert_allclose(trilinear_nodes(np.full((5, 6, 7), 0.3)), 0.3, atol=1e-6)
    # Along one axis, an exponential (Ls inside a medium's surface is like one): the trilinear
    # interpolant of the nodes is closer to it in L2 than the interpolant of its samples (2.3x), and
    # no longer above it on average (11x less).
    n, scale = 24, 4.0
    field = lambda u: np.exp(-u / scale)  # noqa: E731
    samples = np.broadcast_to(field(np.arange(n, dtype=np.float64))[:, None, None], (n, 3, 3))
    nodes = trilinear_nodes(samples)[:, 1, 1].astype(np.float64)
    u = np.linspace(3, n - 4, 200)  # away from the ends, where the fit extrapolates
    errors = {
        name: np.interp(u, np.arange(n), values) - field(u)
        for name, values in (("samples", samples[:, 1, 1]), ("nodes", nodes))
    }
    assert np.sqrt(np.mean(errors["nodes"] ** 2)) < 0.5 * np.sqrt(np.mean(errors["samples"] ** 2))
    assert errors["samples"].mean() > 0 and abs(errors["nodes"].mean()) < 0.15 * errors["samples"].mean()


def test_trilinear_nodes_only_change_the_valid_voxels_and_read_only_valid_samples():
    from mistyle.integrators.inscatter import trilinear_nodes

    valid = np.zeros((12, 12, 12), dtype=bool)
    valid[3:9, 2:10, 4:8] = True
    flat = np.where(valid, 0.6, 1.0)  # outside: the 1.0 that inscattered_radiance leaves there
    nodes = trilinear_nodes(flat, valid=valid)
    np.testing.assert_allclose(nodes[valid], 0.6, atol=1e-6)  # the 1.0s are not read as a cliff
    np.testing.assert_array_equal(nodes[~valid], 1.0)
    assert np.abs(trilinear_nodes(flat)[valid] - 0.6).max() > 0.02
    with pytest.raises(ValueError, match="Z, Y, X"):
        trilinear_nodes(np.ones((4, 4)))
