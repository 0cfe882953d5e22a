"""The one place where torch meets Dr.Jit: albedo volumes in, rendered views out, with gradients.

``render_views`` runs the fast layer (``mistyle_single_scatter``) through ``mi.render`` inside a
``dr.wrap(source='torch', target='drjit')`` function, so ``loss.backward()`` in torch runs the
integrator's adjoint pass and the albedo receives ``dL/d albedo``. Density, Ls and cameras are
constants of the render (no gradient flows to them).

One Mitsuba scene is kept per (grid shape, image size, view count, steps, scheme, radiance) and
its parameters are updated in place, so repeated calls neither reload scenes nor recompile
kernels.

``PathTracedViews`` does the same for the path tracer (``prbvolpath``, multiple scattering), for
refining an albedo against what the final render will show.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence

import numpy as np
import torch

from .backend import ordered_sums, use_variant
from .conventions import DEFAULT_ENV_RADIANCE, LAYER_MARCH_STEPS, ORBIT_DISTANCE
from .conventions import DEFAULT_LAYER_SCHEME as DEFAULT_SCHEME
from .integrators import PreparedDensity, layer_scene
from .scenes import LightSpec, albedo_parameter, pathtraced_scene
from .scenes.cameras import View

_MAX_CACHED_SCENES = 8


def render_views(
    albedo: torch.Tensor,
    density: PreparedDensity | Sequence[PreparedDensity],
    views: Sequence[View],
    image_size: int | tuple[int, int],
    *,
    steps: int = LAYER_MARCH_STEPS,
    scheme: str = DEFAULT_SCHEME,
    radiance: float = DEFAULT_ENV_RADIANCE,
    white: bool = False,
    window: tuple[slice, slice, slice] | None = None,
) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
    """Render albedo volumes with the fast layer from several views.

    Args:
        albedo: ``(B, 3, D, H, W)`` or ``(3, D, H, W)`` float tensor (D=Z, H=Y, W=X), RGB albedo,
            on CPU (``llvm_ad_rgb``) or CUDA (``cuda_ad_rgb``). May require grad.
        density: one ``PreparedDensity`` shared by the batch, or one per batch item.
        views: ``V`` cameras; every batch item is rendered from all of them.
        image_size: ``S`` or ``(height, width)`` of each view in pixels.
        steps: N ray-marching segments per ray.
        scheme: per-segment weight, see ``mistyle.integrators.single_scatter``.
        radiance: constant environment radiance ``Le``.
        white: also return the same views of a white albedo (1 everywhere), computed in the same
            march (the integrator's ``white`` AOVs): what ``objective.masks.body_mask`` finds the
            medium's body in, without a second render.
        window: the ``(D, H, W)`` slices of the density's grid that ``albedo`` covers (a crop, as
            ``model.skpn.occupied_window`` gives); outside them the albedo repeats its faces, as
            ``model.skpn.uncrop`` pads it, and the render is that of the padded albedo. None: the
            albedo covers the whole grid.

    Returns:
        ``(B, V, 3, height, width)`` float32 linear radiance (``(V, 3, height, width)`` for a 4D
        ``albedo``), differentiable with respect to ``albedo``; with ``white``, a pair ``(images,
        white images)`` of that shape, the second without gradient.

    Raises:
        ValueError: wrong albedo rank, channel count, grid size, dtype, device or values; empty
            ``views``; a density list of the wrong length.
    """
    albedo_batch, squeeze = _validate_albedo(albedo)
    batch = albedo_batch.shape[0]
    densities = _validate_densities(density, batch, tuple(albedo_batch.shape[2:]), window)
    height, width = _validate_image_size(image_size)
    views = list(views)
    if not views or not all(isinstance(v, View) for v in views):
        raise ValueError("views must be a non-empty list of mistyle.scenes.View.")

    renderer = _renderer(albedo_batch.device.type, densities[0], height, width, len(views), steps, scheme, radiance)
    films = []
    for item in range(batch):
        # (3, D, H, W) -> the (Z, Y, X, 3) layout of mi.Texture3f; autograd undoes the permute.
        grid = albedo_batch[item].permute(1, 2, 3, 0).to(torch.float32).contiguous()
        state = _RenderState(densities[item], views, window)
        film = renderer.render(grid, state)  # (height, V * width, RGB + white RGB)
        films.append(film.reshape(height, len(views), width, 6).permute(1, 3, 0, 2))
    out = torch.stack(films)
    out = out[0] if squeeze else out
    images = out[..., :3, :, :]
    return (images, out[..., 3:, :, :].detach()) if white else images


class _RenderState:
    """What one render depends on besides the albedo; opaque to Dr.Jit's tree traversal."""

    __slots__ = ("density", "views", "window")

    def __init__(self, density: PreparedDensity, views: list[View], window=None):
        self.density = density
        self.views = views
        self.window = window

    def albedo_box(self) -> tuple[tuple, tuple]:
        """``(albedo_min, albedo_max)`` of the integrator: the window in the box's unit coordinates, x first."""
        shape = self.density.shape
        if self.window is None:
            return (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)
        low = tuple(part.start / size for part, size in zip(self.window, shape))
        high = tuple(part.stop / size for part, size in zip(self.window, shape))
        return low[::-1], high[::-1]


class _LayerRenderer:
    """A loaded layer scene whose albedo, density and cameras are swapped in place.

    Several renders may be recorded before one ``backward()`` (a batch, or frames t and t+1), so
    each render's adjoint pass first restores that render's density and cameras.
    """

    def __init__(self, mi, prepared, height, width, view_count, steps, scheme, radiance):
        import drjit as dr

        placeholder_views = [View(origin=(0.0, 0.0, ORBIT_DISTANCE + v)) for v in range(view_count)]
        albedo = np.zeros(prepared.shape + (3,), dtype=np.float32)
        self.mi = mi
        self.scene = mi.load_dict(
            layer_scene(
                prepared,
                albedo,
                placeholder_views,
                res=(height, width),
                steps=steps,
                scheme=scheme,
                radiance=radiance,
                white=True,  # every render also holds the white views (render_views' white): one channel sum more
            )
        )
        self.params = mi.traverse(self.scene)
        self.current_density: PreparedDensity | None = None
        self.current_views: list[View] | None = None
        self.current_albedo_box: tuple | None = None
        renderer = self

        class LayerOp(dr.CustomOp):
            def eval(self, albedo_grid, state):
                self.albedo_grid, self.state = albedo_grid, state
                renderer.load(state, albedo_grid)
                return renderer.scene.integrator().render(renderer.scene, renderer.scene.sensors()[0], seed=0, spp=1)

            def backward(self):
                params = renderer.load(self.state, dr.detach(self.albedo_grid))
                dr.enable_grad(params["integrator.albedo"])
                params.update()
                integrator = renderer.scene.integrator()
                with ordered_sums():  # the same gradient, bit for bit, every run
                    integrator.render_backward(renderer.scene, params, self.grad_out(), seed=0, spp=1)
                    gradient = dr.grad(params["integrator.albedo"])
                    dr.eval(gradient)
                self.set_grad_in("albedo_grid", gradient)
                dr.disable_grad(params["integrator.albedo"])

            def name(self):
                return "mistyle_single_scatter"

        @dr.wrap(source="torch", target="drjit")
        def render(albedo_grid, state):
            return dr.custom(LayerOp, albedo_grid, state)

        self.render = render

    def load(self, state: _RenderState, albedo_grid):
        """Put one render's albedo, density and cameras into the scene; returns its parameters."""
        mi, params = self.mi, self.params
        params["integrator.albedo"] = albedo_grid
        if state.density is not self.current_density:
            params["integrator.sigma_t"] = mi.TensorXf(state.density.sigma_t[..., None])
            params["integrator.ls"] = mi.TensorXf(state.density.ls[..., None])
            march_min, march_max = state.density.march_bounds
            params["integrator.march_min"] = _opaque_point(mi, march_min)
            params["integrator.march_max"] = _opaque_point(mi, march_max)
            self.current_density = state.density
        if state.views is not self.current_views:
            for index, view in enumerate(state.views):
                prefix = f"sensor.view{index:03d}"
                params[f"{prefix}.to_world"] = mi.ScalarTransform4f().look_at(
                    origin=view.origin, target=view.target, up=view.up
                )
                params[f"{prefix}.x_fov"] = view.fov_deg
            self.current_views = state.views
        albedo_box = state.albedo_box()
        if albedo_box != self.current_albedo_box:
            params["integrator.albedo_min"] = _opaque_point(mi, albedo_box[0])
            params["integrator.albedo_max"] = _opaque_point(mi, albedo_box[1])
            self.current_albedo_box = albedo_box
        params.update()
        return params


def _opaque_point(mi, values):
    """``values`` (x, y, z) as a Point3f the kernel reads from memory: as a literal it would be baked
    into the kernel, which would then compile again for every frame whose box differs."""
    import drjit as dr

    point = mi.Point3f(*map(float, values))
    dr.make_opaque(point)
    return point


_renderers: OrderedDict[tuple, _LayerRenderer] = OrderedDict()


def _renderer(device_type, prepared, height, width, view_count, steps, scheme, radiance) -> _LayerRenderer:
    mi = use_variant(device_type)
    key = (mi.variant(), prepared.shape, height, width, view_count, int(steps), scheme, float(radiance))
    renderer = _renderers.get(key)
    if renderer is None:
        renderer = _LayerRenderer(mi, prepared, height, width, view_count, steps, scheme, radiance)
        _renderers[key] = renderer
        while len(_renderers) > _MAX_CACHED_SCENES:
            _renderers.popitem(last=False)
    _renderers.move_to_end(key)
    return renderer


def _validate_albedo(albedo) -> tuple[torch.Tensor, bool]:
    if not isinstance(albedo, torch.Tensor):
        raise ValueError(f"albedo must be a torch.Tensor (B, 3, D, H, W), got {type(albedo).__name__}.")
    if albedo.dim() not in (4, 5):
        raise ValueError(f"albedo must be (B, 3, D, H, W) or (3, D, H, W), got shape {tuple(albedo.shape)}.")
    squeeze = albedo.dim() == 4
    batch = albedo.unsqueeze(0) if squeeze else albedo
    if batch.shape[1] != 3:
        raise ValueError(f"albedo needs 3 (RGB) channels in dim 1, got shape {tuple(albedo.shape)}.")
    if batch.shape[0] == 0 or min(batch.shape[2:]) == 0:
        raise ValueError(f"albedo is empty: shape {tuple(albedo.shape)}.")
    if batch.dtype not in (torch.float16, torch.bfloat16, torch.float32, torch.float64):
        raise ValueError(f"albedo must be a floating-point tensor, got {batch.dtype}.")
    if batch.device.type not in ("cpu", "cuda"):
        raise ValueError(
            f"albedo is on device {batch.device}; the layer runs on 'cpu' (llvm_ad_rgb) or 'cuda' (cuda_ad_rgb)."
        )
    if batch.device.type == "cuda" and not _cuda_variant_available():
        raise ValueError("albedo is on CUDA but Mitsuba's cuda_ad_rgb variant is unavailable; move it to the CPU.")
    # The sum first (one pass, nothing allocated; a look's fit checks every step's albedo): it is finite
    # whenever every value is, unless finite values overflow it, which the full check then clears.
    if not bool(torch.isfinite(batch.detach().sum())) and not bool(torch.isfinite(batch.detach()).all()):
        raise ValueError("albedo holds NaN or inf values.")
    return batch, squeeze


def _cuda_variant_available() -> bool:
    import drjit as dr

    return bool(dr.has_backend(dr.JitBackend.CUDA))


def _validate_densities(density, batch: int, grid_shape: tuple, window=None) -> list[PreparedDensity]:
    densities = [density] * batch if isinstance(density, PreparedDensity) else list(density)
    if len(densities) != batch or not all(isinstance(d, PreparedDensity) for d in densities):
        raise ValueError(
            f"density must be one PreparedDensity or a list of {batch} (one per batch item); "
            "make them with mistyle.integrators.prepare_density."
        )
    for index, prepared in enumerate(densities):
        if window is None and prepared.shape != grid_shape:
            raise ValueError(
                f"albedo grid (D, H, W) = {grid_shape} does not match density {index} of shape {prepared.shape}."
            )
        if window is not None and not (
            len(window) == 3
            and all(
                isinstance(part, slice) and part.step in (None, 1) and 0 <= part.start < part.stop <= size
                for part, size in zip(window, prepared.shape)
            )
            and tuple(part.stop - part.start for part in window) == grid_shape
        ):
            raise ValueError(
                f"window {window} must be three slices of density {index}'s grid {prepared.shape} whose sizes are "
                f"the albedo grid's {grid_shape}."
            )
    return densities


def _validate_image_size(image_size) -> tuple[int, int]:
    size = (image_size, image_size) if np.isscalar(image_size) else tuple(image_size)
    if len(size) != 2 or any(int(s) != s or s < 1 for s in size):
        raise ValueError(f"image_size must be a positive int or (height, width), got {image_size!r}.")
    return int(size[0]), int(size[1])


class PathTracedViews:
    """Differentiable path-traced views of one density: ``views(albedo, views, seed) -> images``.

    Mitsuba's ``prbvolpath`` (multiple scattering) under a constant environment of ``radiance``
    renders one view at a time from a loaded scene whose camera and albedo are updated in place;
    ``dr.wrap`` carries the albedo gradient back to torch.

    Args:
        density: ``(Z, Y, X)`` numpy, the medium; density_scale: its extinction per unit density.
        res: image side in pixels; spp: paths per pixel of each view.
    """

    def __init__(
        self,
        density: np.ndarray,
        density_scale: float,
        *,
        res: int,
        spp: int = 8,
        radiance: float = DEFAULT_ENV_RADIANCE,
        device: str = "cpu",
    ):
        import drjit as dr

        mi = use_variant(device)
        start = View(origin=(0.0, 0.0, ORBIT_DISTANCE))
        placeholder = np.zeros(density.shape + (3,), np.float32)
        self.mi, self.spp, self.device = mi, int(spp), device
        self.scene = mi.load_dict(
            pathtraced_scene(
                density,
                placeholder,
                [start],
                res=res,
                density_scale=density_scale,
                spp=spp,
                light=LightSpec("constant", radiance),
                integrator="prbvolpath",
            )
        )
        self.params = mi.traverse(self.scene)
        albedo_key = albedo_parameter(self.params)
        params, scene = self.params, self.scene

        @dr.wrap(source="torch", target="drjit")
        def render(grid, seed):
            params[albedo_key] = grid
            params.update()
            return mi.render(scene, params, sensor=0, spp=spp, seed=seed)

        self._render = render

    def __call__(self, albedo: torch.Tensor, views: Sequence[View], seed: int = 0) -> torch.Tensor:
        """``albedo (3, D, H, W)`` in [0, 1] -> ``(V, 3, res, res)`` linear radiance, differentiable.

        View ``v`` is rendered with the seed ``seed + v``.
        """
        batch, _ = _validate_albedo(albedo)
        if batch.shape[0] != 1:
            raise ValueError(f"PathTracedViews renders one albedo (3, D, H, W), got shape {tuple(albedo.shape)}.")
        grid = batch[0].permute(1, 2, 3, 0).to(torch.float32).contiguous()  # the (Z, Y, X, 3) of mi.VolumeGrid
        images = []
        for index, view in enumerate(views):
            self.params["sensor000.to_world"] = self.mi.ScalarTransform4f().look_at(
                origin=view.origin, target=view.target, up=view.up
            )
            images.append(self._render(grid, seed + index).permute(2, 0, 1))
        return torch.stack(images)
