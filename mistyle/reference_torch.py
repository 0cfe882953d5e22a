"""A pure-torch implementation of the fast layer, independent of Mitsuba.

It evaluates the same equation as ``mistyle_single_scatter`` (see that module's docstring) with
its own pinhole camera, ray-box clipping and ``grid_sample`` lookups, and differentiates with
torch autograd. It serves as the reference in tests (any dtype, float64 included) and as the
baseline in ``experiments/bench_layer.py``; training uses the Mitsuba layer.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
import torch.nn.functional as F

from .conventions import DEFAULT_ENV_RADIANCE, LAYER_MARCH_STEPS
from .conventions import DEFAULT_LAYER_SCHEME as DEFAULT_SCHEME
from .conventions import LAYER_SCHEMES as SCHEMES
from .scenes.box import MediumBox
from .scenes.cameras import View


def camera_rays(views: Sequence[View], height: int, width: int, dtype=torch.float64, device="cpu"):
    """Rays through pixel centres of Mitsuba-style perspective cameras.

    Mitsuba's ``look_at`` frame has +x to the camera's left, +y up and +z forward; pixel (0, 0) is
    the top-left corner and ``fov_deg`` spans the image width.

    Returns:
        origins, directions: ``(V, height, width, 3)`` each, directions unit length.
    """
    u = (torch.arange(width, dtype=dtype, device=device) + 0.5) / width
    v = (torch.arange(height, dtype=dtype, device=device) + 0.5) / height
    vv, uu = torch.meshgrid(v, u, indexing="ij")
    origins, directions = [], []
    for view in views:
        origin = torch.tensor(view.origin, dtype=dtype, device=device)
        forward = torch.tensor(view.target, dtype=dtype, device=device) - origin
        forward = forward / forward.norm()
        left = torch.linalg.cross(torch.tensor(view.up, dtype=dtype, device=device), forward)
        left = left / left.norm()
        up = torch.linalg.cross(forward, left)
        half = math.tan(math.radians(view.fov_deg) / 2)
        local_x = (1 - 2 * uu) * half
        local_y = (1 - 2 * vv) * half * height / width
        d = local_x[..., None] * left + local_y[..., None] * up + forward
        directions.append(d / d.norm(dim=-1, keepdim=True))
        origins.append(origin.expand(height, width, 3))
    return torch.stack(origins), torch.stack(directions)


def clip_to_box(origins: torch.Tensor, directions: torch.Tensor, corner_min, corner_max):
    """Slab test against the box ``[corner_min, corner_max]`` (world ``(x, y, z)`` each): entry and exit
    distances ``(...,)`` and a hit mask; zero direction components are safe."""
    lo = torch.as_tensor(corner_min, dtype=origins.dtype, device=origins.device)
    hi = torch.as_tensor(corner_max, dtype=origins.dtype, device=origins.device)
    parallel = directions == 0
    safe = torch.where(parallel, torch.ones_like(directions), directions)
    t_lo, t_hi = (lo - origins) / safe, (hi - origins) / safe
    inside_slab = (origins >= lo) & (origins <= hi)
    inf = torch.full_like(origins, math.inf)
    near = torch.where(parallel, torch.where(inside_slab, -inf, inf), torch.minimum(t_lo, t_hi))
    far = torch.where(parallel, torch.where(inside_slab, inf, -inf), torch.maximum(t_lo, t_hi))
    t_enter = near.amax(dim=-1).clamp_min(0)
    t_exit = far.amin(dim=-1)
    return t_enter, t_exit, t_exit > t_enter


def render_views_torch(
    albedo: torch.Tensor,
    sigma_t: torch.Tensor,
    ls: torch.Tensor,
    views: Sequence[View],
    image_size: tuple[int, int],
    steps: int = LAYER_MARCH_STEPS,
    scheme: str = DEFAULT_SCHEME,
    radiance: float = DEFAULT_ENV_RADIANCE,
) -> torch.Tensor:
    """Render ``(B, 3, D, H, W)`` albedo volumes; returns ``(B, V, 3, height, width)``.

    Args:
        albedo: ``(B, 3, D, H, W)``; its dtype and device are used throughout.
        sigma_t: ``(D, H, W)`` extinction in 1/world-length.
        ls: ``(D, H, W)`` in-scattered radiance for unit environment radiance.
        views, image_size, steps, scheme, radiance: as in ``mistyle.bridge_torch.render_views``.
    """
    if scheme not in SCHEMES:
        raise ValueError(f"Unknown scheme {scheme!r}; choose one of {SCHEMES}.")
    batch = albedo.shape[0]
    height, width = image_size
    box = MediumBox(tuple(albedo.shape[2:]))
    dtype, device = albedo.dtype, albedo.device
    origins, directions = camera_rays(views, height, width, dtype, device)
    # March where the extinction can be non-zero, as the Mitsuba layer does (MediumBox.field_support).
    t_enter, t_exit, hit = clip_to_box(origins, directions, *box.field_support((sigma_t > 0).cpu().numpy()))
    dt = torch.where(hit, (t_exit - t_enter) / steps, torch.zeros_like(t_enter))  # (V, h, w)
    t = t_enter[..., None] + (torch.arange(steps, dtype=dtype, device=device) + 0.5) * dt[..., None]
    points = origins[..., None, :] + directions[..., None, :] * t[..., None]  # (V, h, w, N, 3)
    lo = torch.as_tensor(box.bbox_min, dtype=dtype, device=device)
    extent = torch.as_tensor(box.extent, dtype=dtype, device=device)
    # grid_sample with align_corners=False puts voxel centres at (i + 1/2)/n, like mi.Texture3f;
    # "border" padding is its clamp mode. The grid is (x, y, z) in [-1, 1].
    grid = (2 * (points - lo) / extent - 1).reshape(1, -1, 1, 1, 3)

    def lookup(volume):  # (C, D, H, W) -> (C, V, h, w, N)
        sampled = F.grid_sample(volume[None], grid, mode="bilinear", padding_mode="border", align_corners=False)
        return sampled.reshape(volume.shape[0], *points.shape[:-1])

    constants = lookup(torch.stack([sigma_t, ls]).to(dtype))
    tau = constants[0] * dt[..., None]
    optical_depth = torch.cumsum(tau, dim=-1)
    T_after = torch.exp(-optical_depth)
    T_before = torch.exp(-(optical_depth - tau))
    if scheme == "riemann":
        weight = T_after * tau
    elif scheme == "midpoint":
        weight = T_before * torch.exp(-0.5 * tau) * tau
    else:
        weight = T_before - T_after
    weight = radiance * weight * constants[1]  # (V, h, w, N)
    images = [(lookup(albedo[b]) * weight).sum(dim=-1).permute(1, 0, 2, 3) for b in range(batch)]
    return torch.stack(images)
