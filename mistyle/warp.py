"""Semi-Lagrangian warping of volumes by a velocity field: one convention for data and losses.

``warp(V, U)(x) = V(x - U(x))``: each voxel looks back along the velocity and reads the volume
there with trilinear interpolation, clamped at the border. Velocities are in voxels per frame,
components in ``(x, y, z)`` order; warping frame t by its velocity predicts frame t+1.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F


def semi_lagrangian_warp(volume: torch.Tensor, velocity: torch.Tensor) -> torch.Tensor:
    """Warp ``volume (B, C, D, H, W)`` by ``velocity (B, 3, D, H, W)``; differentiable in both.

    Returns:
        ``(B, C, D, H, W)``.
    """
    if volume.dim() != 5 or velocity.dim() != 5 or velocity.shape[1] != 3:
        raise ValueError(
            f"Expected volume (B,C,D,H,W) and velocity (B,3,D,H,W), "
            f"got {tuple(volume.shape)} and {tuple(velocity.shape)}."
        )
    if volume.shape[0] != velocity.shape[0] or volume.shape[2:] != velocity.shape[2:]:
        raise ValueError(
            f"volume {tuple(volume.shape)} and velocity {tuple(velocity.shape)} must share batch and grid."
        )
    batch, _, depth, height, width = volume.shape
    z, y, x = torch.meshgrid(
        *(torch.arange(n, dtype=volume.dtype, device=volume.device) for n in (depth, height, width)), indexing="ij"
    )
    back_x = x - velocity[:, 0]
    back_y = y - velocity[:, 1]
    back_z = z - velocity[:, 2]

    def normalise(index, size):  # voxel index -> [-1, 1] with align_corners=True
        return 2.0 * index / max(size - 1, 1) - 1.0

    grid = torch.stack([normalise(back_x, width), normalise(back_y, height), normalise(back_z, depth)], dim=-1)
    return F.grid_sample(volume, grid, mode="bilinear", padding_mode="border", align_corners=True)


def warp_grid(field: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """``semi_lagrangian_warp`` on numpy grids: ``field(x - velocity(x))``.

    ``field`` is ``(Z, Y, X)`` or ``(Z, Y, X, C)``; ``velocity`` ``(Z, Y, X, 3)`` in voxels, ``(x, y, z)``.
    """
    values = torch.as_tensor(np.asarray(field, dtype=np.float32))
    channels_last = values.dim() == 4
    volume = values.permute(3, 0, 1, 2)[None] if channels_last else values[None, None]
    flow = torch.as_tensor(np.asarray(velocity, dtype=np.float32)).permute(3, 0, 1, 2)[None]
    warped = semi_lagrangian_warp(volume, flow)[0]
    return (warped.permute(1, 2, 3, 0) if channels_last else warped[0]).numpy()
