"""Small differentiable geometry helpers in torch (the optimiser's side of the kernels)."""

from __future__ import annotations

import torch

from warpskill.engine.primitives import cuboid_vertices


def box_signed_distance(points: torch.Tensor, pos: torch.Tensor, rot: torch.Tensor, size: torch.Tensor) -> torch.Tensor:
    """Signed distance [m] of world points to cuboids, negative inside.

    Args:
        points: (..., 3) world points.
        pos, rot, size: (..., 3), (..., 3, 3), (..., 3) cuboid centres, rotations, full sizes.

    Returns:
        (...) signed distances.
    """
    local = ((points - pos)[..., None, :] @ rot).squeeze(-2)
    q = local.abs() - 0.5 * size
    outside = q.clamp_min(0.0).square().sum(-1).add(1e-12).sqrt()
    inside = q.amax(-1).clamp_max(0.0)
    return outside + inside


def lowest_corner_height(pos: torch.Tensor, rot: torch.Tensor, size: torch.Tensor) -> torch.Tensor:
    """World height [m] of each cuboid's lowest corner, (...,)."""
    return cuboid_vertices(pos, rot, size)[..., 2].amin(-1)


def static_exits(pos: torch.Tensor, rot: torch.Tensor, size: torch.Tensor, static_pos: torch.Tensor,
                 static_rot: torch.Tensor, static_size: torch.Tensor) -> torch.Tensor:
    """How far [m] each cuboid must move to leave each static cuboid, (..., K, 5): along the
    static's +x, -x, +y, -y and up (world z; statics are yawed only), comparing the cuboid's
    corners with the static's faces. All five are positive only where the two overlap; the
    smallest is then the overlap's depth and its index the shortest way out (a yawed cuboid's
    corners overstate it a little).

    Args:
        pos, rot, size: (..., 3), (..., 3, 3), (..., 3) or (3,) cuboids.
        static_pos, static_rot, static_size: (K, 3), (K, 3, 3), (K, 3) static cuboids.
    """
    corners = cuboid_vertices(pos, rot, size)  # (..., 8, 3)
    local = torch.einsum("...kvj,kji->...kvi", corners.unsqueeze(-3) - static_pos[:, None], static_rot)
    low, high, half = local.amin(-2), local.amax(-2), 0.5 * static_size
    return torch.stack([half[:, 0] - low[..., 0], high[..., 0] + half[:, 0], half[:, 1] - low[..., 1],
                        high[..., 1] + half[:, 1], half[:, 2] - low[..., 2]], -1)


def static_overlap_depth(pos: torch.Tensor, rot: torch.Tensor, size: torch.Tensor, static_pos: torch.Tensor,
                         static_rot: torch.Tensor, static_size: torch.Tensor) -> torch.Tensor:
    """How deep [m] each cuboid reaches into each static cuboid, (..., K): the shortest of
    :func:`static_exits`'s ways out where all five are positive, else 0."""
    return static_exits(pos, rot, size, static_pos, static_rot, static_size).amin(-1).clamp_min(0.0)


def support_height(points: torch.Tensor, static_pos: torch.Tensor, static_rot: torch.Tensor, static_size: torch.Tensor) -> torch.Tensor:
    """Height [m] of the surface under each point: a static cuboid's top where the point
    lies over its footprint, else the ground (0).

    Args:
        points: (N, 3) world points (only x, y matter).
        static_pos, static_rot, static_size: (K, 3), (K, 3, 3), (K, 3) static cuboids.

    Returns:
        (N,) support heights (no gradient through which support is chosen).
    """
    if len(static_pos) == 0:
        return points.new_zeros(len(points))
    local = torch.einsum("nkj,kji->nki", points[:, None, :] - static_pos[None], static_rot)  # (N, K, 3)
    inside = (local[..., :2].abs() < 0.5 * static_size[None, :, :2]).all(-1)
    tops = (static_pos[:, 2] + 0.5 * static_size[:, 2])[None].expand_as(inside)
    return torch.where(inside, tops, torch.zeros_like(tops)).amax(-1)
