"""Rotation parameterisations used by the optimiser (torch, differentiable)."""

from __future__ import annotations

import torch


def rotation_from_6d(x: torch.Tensor) -> torch.Tensor:
    """Rotation matrices from the continuous 6D representation (Zhou et al., CVPR 2019).

    Args:
        x: (..., 6) the first two columns of a rotation, unnormalised.

    Returns:
        (..., 3, 3) rotation matrices (Gram-Schmidt on the two columns).
    """
    a, b = x[..., :3], x[..., 3:]
    c1 = torch.nn.functional.normalize(a, dim=-1)
    c2 = torch.nn.functional.normalize(b - (c1 * b).sum(-1, keepdim=True) * c1, dim=-1)
    c3 = torch.cross(c1, c2, dim=-1)
    return torch.stack([c1, c2, c3], dim=-1)


def rotation_to_6d(R: torch.Tensor) -> torch.Tensor:
    """The 6D representation of rotations (..., 3, 3): their first two columns, (..., 6)."""
    return torch.cat([R[..., :, 0], R[..., :, 1]], dim=-1)


def yaw_rotation(yaw: torch.Tensor) -> torch.Tensor:
    """Rotations about world z by ``yaw`` [rad], (...,) -> (..., 3, 3)."""
    c, s = torch.cos(yaw), torch.sin(yaw)
    zero, one = torch.zeros_like(yaw), torch.ones_like(yaw)
    return torch.stack(
        [torch.stack([c, -s, zero], -1), torch.stack([s, c, zero], -1), torch.stack([zero, zero, one], -1)], -2
    )


def rotation_log(R: torch.Tensor) -> torch.Tensor:
    """Axis-angle vectors (..., 3) [rad] of rotations (..., 3, 3) with angle < pi."""
    cos = ((R.diagonal(dim1=-2, dim2=-1).sum(-1) - 1.0) / 2.0).clamp(-1.0 + 1e-6, 1.0 - 1e-6)
    angle = torch.acos(cos)
    axis = torch.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    scale = torch.where(angle < 1e-4, 0.5 + angle**2 / 12.0, angle / (2.0 * torch.sin(angle)))
    return axis * scale[..., None]
