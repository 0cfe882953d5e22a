"""render_views: shapes, batches, bad input, and no memory growth across calls."""

import gc
import os

import numpy as np
import pytest
import torch

from mistyle.bridge_torch import render_views
from mistyle.integrators import prepare_density
from mistyle.scenes import CameraPath

VIEWS = CameraPath().turntable(3)


@pytest.fixture(scope="module")
def prepared(mi, blob_density):
    return prepare_density(blob_density, 20.0, directions=16)


def test_output_shapes(prepared):
    albedo = torch.rand((2, 3) + prepared.shape)
    assert render_views(albedo, prepared, VIEWS, 12).shape == (2, 3, 3, 12, 12)
    assert render_views(albedo[0], prepared, VIEWS[:1], (10, 14)).shape == (1, 3, 10, 14)


def test_batch_items_use_their_own_density_and_views_in_backward(prepared, blob_density):
    """Several renders recorded before one backward() each get their own density and cameras."""
    other = prepare_density(np.roll(blob_density, 3, axis=2), 35.0, directions=16)
    albedo = torch.rand((2, 3) + prepared.shape)
    weights = torch.rand((2, 3, 3, 12, 12))

    def grads(together: bool):
        leaf = albedo.clone().requires_grad_()
        if together:
            first = render_views(leaf, [prepared, other], VIEWS, 12)
            second = render_views(leaf[:1], prepared, VIEWS[::-1], 12)  # a later render, other views
            ((first * weights).sum() + (second * weights[:1]).sum()).backward()
            return leaf.grad
        total = torch.zeros_like(albedo)
        for item, density in enumerate([prepared, other]):
            part = albedo[item : item + 1].clone().requires_grad_()
            (render_views(part, density, VIEWS, 12) * weights[item : item + 1]).sum().backward()
            total[item] += part.grad[0]
        part = albedo[:1].clone().requires_grad_()
        (render_views(part, prepared, VIEWS[::-1], 12) * weights[:1]).sum().backward()
        total[0] += part.grad[0]
        return total

    torch.testing.assert_close(grads(True), grads(False), rtol=1e-5, atol=1e-7)


def test_the_white_views_come_with_the_render_and_leave_its_image_and_gradient_as_they_were(prepared):
    """``white=True`` gives a white albedo's views from the same march (the integrator's AOVs): equal to
    rendering a white albedo, with the RGB image and its gradient as without them."""
    albedo = torch.rand((3,) + prepared.shape, generator=torch.Generator().manual_seed(5))
    weights = torch.rand((3, 3, 12, 12), generator=torch.Generator().manual_seed(6))
    leaf = albedo.clone().requires_grad_()
    images, white = render_views(leaf, prepared, VIEWS, 12, white=True)
    (images * weights).sum().backward()
    assert not white.requires_grad and white.shape == images.shape
    with torch.no_grad():
        torch.testing.assert_close(
            white, render_views(torch.ones_like(albedo), prepared, VIEWS, 12), rtol=1e-5, atol=1e-6
        )
        assert float(white.amax()) > 0.1
    plain = albedo.clone().requires_grad_()
    plain_images = render_views(plain, prepared, VIEWS, 12)
    (plain_images * weights).sum().backward()
    torch.testing.assert_close(images, plain_images, rtol=0, atol=0)
    torch.testing.assert_close(leaf.grad, plain.grad, rtol=0, atol=0)


def test_an_albedo_on_a_window_renders_as_the_whole_grid_padded_by_its_faces(prepared):
    """``window``: a look's fit renders the albedo of its crop alone; image and gradient are those of the
    albedo padded to the grid (``uncrop``), and the next whole-grid render is as before."""
    from mistyle.model.skpn import uncrop

    window = (slice(2, 13), slice(4, 16), slice(4, 18))
    part = torch.rand((3, 11, 12, 14), generator=torch.Generator().manual_seed(1))
    weights = torch.rand((3, 3, 16, 16), generator=torch.Generator().manual_seed(2))

    def image_and_gradient(cropped: bool):
        leaf = part.clone().requires_grad_()
        albedo = leaf if cropped else uncrop(leaf[None], window, prepared.shape)[0]
        image = render_views(albedo, prepared, VIEWS, 16, window=window if cropped else None)
        (image * weights).sum().backward()
        return image.detach(), leaf.grad

    padded, padded_grad = image_and_gradient(False)
    cropped, cropped_grad = image_and_gradient(True)
    torch.testing.assert_close(cropped, padded, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(cropped_grad, padded_grad, rtol=1e-4, atol=1e-6)
    whole = uncrop(part[None], window, prepared.shape)[0]
    torch.testing.assert_close(render_views(whole, prepared, VIEWS, 16), padded, rtol=0, atol=0)
    with pytest.raises(ValueError, match="window"):
        render_views(part, prepared, VIEWS, 16, window=(slice(2, 13), slice(4, 16), slice(4, 19)))


def test_a_cached_scene_takes_the_next_densitys_grids_and_march_box(mi, prepared, blob_density):
    from mistyle.integrators import layer_scene
    from mistyle.scenes import split_views

    other = prepare_density(np.roll(blob_density, 4, axis=2), 20.0, directions=16)
    assert not np.allclose(other.march_bounds[1], prepared.march_bounds[1])
    albedo = torch.rand((3,) + prepared.shape, generator=torch.Generator().manual_seed(3))
    render_views(albedo, prepared, VIEWS, 12)  # loads the scene with the first density
    through_cache = render_views(albedo, other, VIEWS, 12)
    fresh = mi.load_dict(layer_scene(other, albedo.permute(1, 2, 3, 0).numpy(), VIEWS, res=12))
    expected = torch.from_numpy(split_views(mi.render(fresh), len(VIEWS))).permute(0, 3, 1, 2)
    torch.testing.assert_close(through_cache, expected, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize(
    "albedo,match",
    [
        (torch.rand(3, 16, 18), "\\(B, 3, D, H, W\\)"),
        (torch.rand(1, 4, 16, 18, 20), "3 \\(RGB\\) channels"),
        (torch.rand(1, 3, 16, 18, 21), "does not match density"),
        (torch.ones(1, 3, 16, 18, 20, dtype=torch.int32), "floating-point"),
        (torch.full((1, 3, 16, 18, 20), float("nan")), "NaN"),
        (torch.rand(1, 3, 16, 18, 20).index_put_((torch.tensor([0]),) * 5, torch.tensor(float("inf"))), "NaN or inf"),
        (torch.rand(1, 3, 16, 18, 20, device="meta"), "device"),
        (np.zeros((1, 3, 16, 18, 20), np.float32), "torch.Tensor"),
    ],
)
def test_bad_albedo_raises_value_error(prepared, albedo, match):
    with pytest.raises(ValueError, match=match):
        render_views(albedo, prepared, VIEWS, 8)


def test_finite_albedos_whose_sum_overflows_pass_the_check():
    from mistyle.bridge_torch import _validate_albedo

    huge = torch.full((1, 3, 16, 18, 20), 3e38)
    assert not torch.isfinite(huge.sum())
    assert _validate_albedo(huge)[0] is huge


def test_bad_views_and_density_lists_raise(prepared):
    albedo = torch.rand((2, 3) + prepared.shape)
    with pytest.raises(ValueError, match="views"):
        render_views(albedo, prepared, [], 8)
    with pytest.raises(ValueError, match="list of 2"):
        render_views(albedo, [prepared], VIEWS, 8)
    with pytest.raises(ValueError, match="image_size"):
        render_views(albedo, prepared, VIEWS, 0)


@pytest.mark.parametrize(
    "density,match",
    [
        (np.full((4, 4, 4), np.nan, np.float32), "NaN"),
        (np.full((4, 4, 4), np.inf, np.float32), "NaN/inf"),
        (-np.ones((4, 4, 4), np.float32), "negative"),
        (np.ones((4, 4), np.float32), "3D array"),
        (np.ones((0, 4, 4), np.float32), "empty"),
    ],
)
def test_bad_density_raises_value_error(mi, density, match):
    with pytest.raises(ValueError, match=match):
        prepare_density(density, 20.0)


def test_bad_density_scale_raises(mi):
    with pytest.raises(ValueError, match="density_scale"):
        prepare_density(np.ones((4, 4, 4), np.float32), -1.0)


def test_memory_does_not_grow_over_200_calls(prepared):
    albedo = torch.rand((1, 3) + prepared.shape)

    def step():
        leaf = albedo.clone().requires_grad_()
        render_views(leaf, prepared, VIEWS, 16).sum().backward()

    for _ in range(20):  # compile kernels, fill allocator caches
        step()
    gc.collect()
    before = resident_mib()
    for _ in range(200):
        step()
    gc.collect()
    grown = resident_mib() - before
    assert grown < 20, f"resident memory grew by {grown:.1f} MiB over 200 forward+backward calls"


def resident_mib() -> float:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
