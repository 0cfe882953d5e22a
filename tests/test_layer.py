"""The fast layer: analytic radiance, finite-difference and pure-torch gradient checks."""

import numpy as np
import pytest
import torch

from mistyle.bridge_torch import render_views
from mistyle.integrators import PreparedDensity, prepare_density
from mistyle.reference_torch import camera_rays, clip_to_box, render_views_torch
from mistyle.scenes import CameraPath, MediumBox, View

VIEWS = CameraPath().turntable(2, offset=0.05)
SIZE = (20, 24)


@pytest.fixture(scope="module")
def blob(mi, blob_density):
    return prepare_density(blob_density, 20.0, directions=32)


def random_albedo(shape, seed=0, dtype=torch.float32):
    generator = torch.Generator().manual_seed(seed)
    return (0.1 + 0.8 * torch.rand((1, 3) + tuple(shape), generator=generator)).to(dtype)


@pytest.mark.parametrize("scheme", ["exact", "midpoint", "riemann"])
def test_homogeneous_slab_matches_closed_form(mi, scheme):
    """Constant sigma, Ls = 1, albedo a: L = Le a (1 - exp(-sigma l)) along a chord of length l."""
    shape, sigma, a = (8, 8, 8), 3.0, 0.6
    prepared = PreparedDensity(np.full(shape, sigma, np.float32), 1.0, np.ones(shape, np.float32))
    view = View(origin=(0.3, 0.2, 2.0), fov_deg=30.0)
    image = render_views(torch.full((3,) + shape, a), prepared, [view], (9, 9), steps=32, scheme=scheme, radiance=2.5)[
        0, 0
    ]
    origins, directions = camera_rays([view], 9, 9)
    t0, t1, hit = clip_to_box(origins, directions, MediumBox(shape).bbox_min, MediumBox(shape).bbox_max)
    expected = a * (1 - torch.exp(-sigma * (t1 - t0).clamp_min(0)))[0] * hit[0]
    tolerance = 1e-5 if scheme == "exact" else 2e-2
    torch.testing.assert_close(image.double() / 2.5, expected, atol=tolerance, rtol=tolerance)


def test_empty_density_renders_black(mi):
    prepared = prepare_density(np.zeros((8, 8, 8), np.float32), 20.0, directions=8)
    image = render_views(torch.rand(3, 8, 8, 8), prepared, VIEWS, SIZE)
    assert torch.count_nonzero(image) == 0


def test_gradient_matches_central_differences_in_float64(mi, blob):
    """The image is linear in albedo, so a large step gives exact differences up to rounding."""
    albedo = random_albedo(blob.shape)
    weights = torch.rand((1, len(VIEWS), 3) + SIZE, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    direction = torch.randn(albedo.shape, generator=torch.Generator().manual_seed(2))

    def loss(a):
        return (render_views(a, blob, VIEWS, SIZE).double() * weights).sum()

    leaf = albedo.clone().requires_grad_()
    loss(leaf).backward()
    analytic = (leaf.grad.double() * direction.double()).sum()
    step = 0.25
    with torch.no_grad():
        numeric = (loss(albedo + step * direction) - loss(albedo - step * direction)) / (2 * step)
    assert abs(float(analytic - numeric)) <= 1e-4 * abs(float(numeric))


def test_matches_pure_torch_reference_in_float64(mi, blob):
    albedo = random_albedo(blob.shape, seed=3)
    weights = torch.rand((1, len(VIEWS), 3) + SIZE, generator=torch.Generator().manual_seed(4), dtype=torch.float64)
    leaf = albedo.clone().requires_grad_()
    image = render_views(leaf, blob, VIEWS, SIZE)
    (image.double() * weights).sum().backward()

    reference_leaf = albedo.double().requires_grad_()
    sigma_t, ls = torch.from_numpy(blob.sigma_t).double(), torch.from_numpy(blob.ls).double()
    reference = render_views_torch(reference_leaf, sigma_t, ls, VIEWS, SIZE)
    (reference * weights).sum().backward()

    assert float((image.detach().double() - reference.detach()).norm() / reference.detach().norm()) <= 1e-4
    assert float((leaf.grad.double() - reference_leaf.grad).norm() / reference_leaf.grad.norm()) <= 1e-4
    assert torch.isfinite(leaf.grad).all()


def test_marching_only_where_the_medium_is_converges_to_the_same_image_sooner(mi, blob):
    """Rays are marched through the extinction's support (``MediumBox.field_support``), not the whole box:
    the same integral, so the same converged image, and at few steps a smaller error."""
    from mistyle.integrators import layer_scene
    from mistyle.scenes import split_views

    albedo = random_albedo(blob.shape, seed=6)[0].permute(1, 2, 3, 0).numpy()
    low, high = blob.march_bounds
    assert np.all(high - low < 0.95 * blob.box.extent)  # the blob leaves margins to skip

    def render(steps, whole_box):
        scene = layer_scene(blob, albedo, VIEWS, res=SIZE, steps=steps)
        if whole_box:
            scene["integrator"]["march_min"] = scene["integrator"]["bbox_min"]
            scene["integrator"]["march_max"] = scene["integrator"]["bbox_max"]
        return split_views(mi.render(mi.load_dict(scene)), len(VIEWS)).astype(np.float64)

    converged = render(4096, whole_box=True)
    assert np.abs(render(4096, whole_box=False) - converged).max() < 1e-4 * converged.max()
    # Per step count the error also depends on how the samples fall on the voxel lattice; on average
    # the shorter segments win (here by 1.6x).
    error = {
        whole: np.mean([np.sqrt(np.mean((render(n, whole) - converged) ** 2)) for n in (8, 12, 16, 32, 48)])
        for whole in (True, False)
    }
    assert error[False] < 0.8 * error[True]
    scene = layer_scene(blob, albedo, VIEWS, res=SIZE)
    scene["integrator"]["march_max"] = mi.ScalarPoint3f(2.0, 0.0, 0.0)
    with pytest.raises(Exception, match="inside the medium box"):
        mi.load_dict(scene)


def test_prepare_density_gives_the_layer_fitted_nodes_for_computed_and_cached_ls(mi, blob_density):
    from mistyle.integrators.inscatter import inscattered_radiance, layer_reads_ls, trilinear_nodes

    sigma_t = blob_density * np.float32(20.0)
    samples = inscattered_radiance(sigma_t, directions=16)
    computed = prepare_density(blob_density, 20.0, directions=16)
    cached = prepare_density(blob_density, 20.0, directions=16, ls=samples)
    expected = trilinear_nodes(samples, valid=layer_reads_ls(sigma_t))
    np.testing.assert_allclose(computed.ls, expected, rtol=1e-6)
    np.testing.assert_array_equal(cached.ls, computed.ls)
    assert np.abs(computed.ls - samples).max() > 1e-3  # the nodes are not the samples


def test_exact_scheme_needs_fewer_steps_than_riemann(mi, blob):
    """Against a 1024-step render, the exact segment weight converges faster than the paper's sum."""
    albedo = random_albedo(blob.shape, seed=5)
    converged = render_views(albedo, blob, VIEWS, SIZE, steps=1024, scheme="exact")
    errors = {
        scheme: float((render_views(albedo, blob, VIEWS, SIZE, steps=16, scheme=scheme) - converged).norm())
        for scheme in ("exact", "riemann")
    }
    assert errors["exact"] < errors["riemann"]


def test_forward_mode_of_the_integrator_renders_the_albedo_tangent(mi, blob):
    """The image is linear in the albedo: its forward-mode derivative along δα is the render of δα."""
    import drjit as dr

    from mistyle.integrators import layer_scene
    from mistyle.scenes import split_views

    albedo = random_albedo(blob.shape, seed=1)[0].permute(1, 2, 3, 0).numpy()
    tangent = random_albedo(blob.shape, seed=2)[0].permute(1, 2, 3, 0).numpy()
    scene = mi.load_dict(layer_scene(blob, albedo, VIEWS, res=SIZE))
    params = mi.traverse(scene)
    dr.enable_grad(params["integrator.albedo"])
    params.update()
    dr.set_grad(params["integrator.albedo"], mi.TensorXf(tangent))
    derivative = split_views(scene.integrator().render_forward(scene, params, sensor=0, seed=0, spp=1), len(VIEWS))
    dr.disable_grad(params["integrator.albedo"])
    params["integrator.albedo"] = mi.TensorXf(tangent)
    params.update()
    direct = split_views(mi.render(scene), len(VIEWS))
    assert np.abs(direct).max() > 0.05
    np.testing.assert_allclose(derivative, direct, rtol=1e-4, atol=1e-6)


def test_ls_on_a_finer_grid_renders_through_the_layer_and_the_bridge(mi, blob):
    """``prepare_density(ls_grid_factor=3)``: the layer reads Ls at any multiple of the density's grid; the
    image stays within a few percent of the density-grid Ls (the finer grid removes a bias of ~1%)."""
    fine = prepare_density(blob.density, blob.density_scale, 32, ls_grid_factor=3)
    assert fine.ls.shape == tuple(3 * n for n in blob.density.shape) and fine.ls_grid_factor == 3
    coarse = prepare_density(blob.density, blob.density_scale, 32)
    albedo = torch.full((1, 3) + blob.density.shape, 0.7)
    images = [render_views(albedo, prepared, VIEWS, SIZE) for prepared in (coarse, fine, coarse)]
    assert torch.equal(images[0], images[2])  # the bridge swaps the Ls grid back and forth
    relative = float(((images[1] - images[0]).pow(2).mean() / images[0].pow(2).mean()).sqrt())
    assert 1e-4 < relative < 0.05
    with pytest.raises(ValueError, match="whole multiple"):
        PreparedDensity(blob.density, blob.density_scale, np.ones((5, 5, 5), np.float32))
