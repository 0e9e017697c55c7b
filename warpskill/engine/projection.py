"""The camera's extrinsics and projection, differentiable in Torch (``docs/formats.md``, "Camera").

World frame: z up, ground at z = 0, x to the image's right, y away from the camera.
The optical centre sits at ``(0, 0, height)``; the camera looks along +y, pitched down by
``elevation`` [rad]. Camera axes follow OpenCV (x right, y down, z forward). Image
coordinates are continuous, with the centre of pixel (row i, column j) at (j + 0.5, i + 0.5).

All functions take and return Torch tensors so that gradients reach the camera's height
and elevation; the intrinsics (:class:`warpskill.contract.camera.Intrinsics`) are fixed.
"""

from __future__ import annotations

import numpy as np
import torch


def camera_rotation(elevation: torch.Tensor) -> torch.Tensor:
    """Camera-to-world rotation R_wc for a camera pitched down by ``elevation`` [rad].

    Args:
        elevation: scalar tensor (or any shape ``S``).

    Returns:
        (*S, 3, 3) tensor whose columns are the camera's x, y, z axes in the world.
    """
    e = torch.as_tensor(elevation)
    s, c = torch.sin(e), torch.cos(e)
    zero, one, minus_s = torch.zeros_like(e), torch.ones_like(e), -s
    return torch.stack([one, zero, zero, zero, minus_s, c, zero, -c, minus_s], dim=-1).unflatten(-1, (3, 3))


def world_to_camera(points: torch.Tensor, height: torch.Tensor, elevation: torch.Tensor) -> torch.Tensor:
    """Express world points [m] in the camera frame: ``R_wc^T (p - c)``.

    Args:
        points: (..., 3) world points.
        height: scalar camera height [m].
        elevation: scalar camera elevation [rad].

    Returns:
        (..., 3) camera-frame points (z is the depth along the optical axis).
    """
    R = camera_rotation(elevation).to(points)
    h = torch.as_tensor(height).to(points)
    centre = torch.stack([torch.zeros_like(h), torch.zeros_like(h), h])
    return (points - centre) @ R


def camera_to_world(points: torch.Tensor, height: torch.Tensor, elevation: torch.Tensor) -> torch.Tensor:
    """Inverse of :func:`world_to_camera`."""
    R = camera_rotation(elevation).to(points)
    h = torch.as_tensor(height).to(points)
    centre = torch.stack([torch.zeros_like(h), torch.zeros_like(h), h])
    return points @ R.transpose(-1, -2) + centre


def project(points_cam: torch.Tensor, K: torch.Tensor | np.ndarray, *, min_depth: float = 1e-3) -> torch.Tensor:
    """Pinhole projection of camera-frame points to continuous pixel coordinates.

    Args:
        points_cam: (..., 3) camera-frame points [m].
        K: (3, 3) intrinsics [px].
        min_depth: depths below this [m] are clamped (points behind the camera must be
            clipped by the caller; the clamp only keeps the division finite).

    Returns:
        (..., 2) pixel coordinates (u, v).
    """
    K = torch.as_tensor(K, dtype=points_cam.dtype, device=points_cam.device)
    z = points_cam[..., 2].clamp_min(min_depth)
    u = K[0, 0] * points_cam[..., 0] / z + K[0, 2]
    v = K[1, 1] * points_cam[..., 1] / z + K[1, 2]
    return torch.stack([u, v], dim=-1)
