"""Scene primitives as convex n-prisms (``docs/formats.md``, "Scene primitives").

A prism with n sides has 2n vertices: the bottom ring (counter-clockwise about the local
+z axis), then the top ring in the same order, so vertex k and vertex n + k share their
local (x, y). A cuboid is a 4-prism; the hand is a 24-prism whose circumradius is scaled
so that its cross-section area equals the true cylinder's.

All functions take and return Torch tensors so that gradients reach poses, sizes and the
camera.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from warpskill.contract.vocabulary import MODEL_HAND_LENGTH as HAND_LENGTH  # local z in [0, HAND_LENGTH]
from warpskill.contract.vocabulary import MODEL_HAND_RADIUS as HAND_RADIUS
from warpskill.engine.projection import camera_rotation

HAND_SEGMENTS = 24
"""Sides of the prism that stands in for the hand cylinder."""

HAND_PRISM_RADIUS = HAND_RADIUS * math.sqrt(2.0 * math.pi / (HAND_SEGMENTS * math.sin(2.0 * math.pi / HAND_SEGMENTS)))
"""Circumradius [m] of the regular HAND_SEGMENTS-gon with the cylinder's cross-section area."""

NEAR_PLANE = 0.05
"""Depth [m] in front of the camera that every rendered vertex must keep."""

_CUBOID_CORNERS = torch.tensor(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]],
    dtype=torch.float64,
)


def cuboid_vertices(pos: torch.Tensor, rot: torch.Tensor, size: torch.Tensor) -> torch.Tensor:
    """World vertices of cuboids as 4-prisms about their local z axis.

    Args:
        pos: (..., 3) centres [m].
        rot: (..., 3, 3) local-to-world rotations.
        size: (..., 3) full edge lengths [m] along the local axes.

    Returns:
        (..., 8, 3) vertices [m]: bottom ring (local z = -sz / 2), then top ring.
    """
    local = _CUBOID_CORNERS.to(pos) * (0.5 * size).unsqueeze(-2)
    return local @ rot.transpose(-1, -2) + pos.unsqueeze(-2)


def hand_vertices(
    pos: torch.Tensor, rot: torch.Tensor, *, extent: tuple[torch.Tensor, torch.Tensor] | None = None
) -> torch.Tensor:
    """World vertices of the hand prism.

    Args:
        pos: (..., 3) hand tip positions [m].
        rot: (..., 3, 3) hand-to-world rotations (the axis is the local +z column).
        extent: optional (t0, t1), each (...), the part of the axis [m] to keep; default
            (0, HAND_LENGTH). See :func:`hand_axis_extent`.

    Returns:
        (..., 2 * HAND_SEGMENTS, 3) vertices [m]: the ring at t0, then the ring at t1.
    """
    angle = torch.arange(HAND_SEGMENTS, dtype=pos.dtype, device=pos.device) * (2.0 * math.pi / HAND_SEGMENTS)
    ring = HAND_PRISM_RADIUS * torch.stack([torch.cos(angle), torch.sin(angle)], dim=-1)  # (n, 2)
    if extent is None:
        t0, t1 = torch.zeros_like(pos[..., 0]), torch.full_like(pos[..., 0], HAND_LENGTH)
    else:
        t0, t1 = (torch.as_tensor(t).to(pos).expand(pos.shape[:-1]) for t in extent)
    t = torch.stack([t0, t1], dim=-1).repeat_interleave(HAND_SEGMENTS, dim=-1)  # (..., 2n)
    xy = ring.repeat(2, 1).expand(*pos.shape[:-1], -1, -1)  # (..., 2n, 2)
    local = torch.cat([xy, t.unsqueeze(-1)], dim=-1)
    return local @ rot.transpose(-1, -2) + pos.unsqueeze(-2)


def hand_axis_extent(
    pos: torch.Tensor,
    rot: torch.Tensor,
    camera_height: torch.Tensor,
    camera_elevation: torch.Tensor,
    *,
    near: float = NEAR_PLANE,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Clip the hand's axis so that every prism vertex stays ``near`` in front of the camera.

    The kept part [t0, t1] of the axis is the largest one on which both end rings (of the
    prism's circumradius, hence the cylinder too) have depth >= ``near``; the arm, which
    usually runs towards or behind the camera, is cut perpendicular to its axis.

    Args:
        pos: (..., 3) hand tip positions [m].
        rot: (..., 3, 3) hand-to-world rotations.
        camera_height: scalar camera height [m].
        camera_elevation: scalar camera elevation [rad].
        near: near-plane depth [m].

    Returns:
        t0, t1: (...) kept axis range [m], 0 <= t0 <= t1 <= HAND_LENGTH.
        visible: (...) bool, False where no part of the hand is in front of the near plane
            (t0, t1 are then finite but meaningless).
    """
    forward = camera_rotation(camera_elevation).to(pos)[..., :, 2]  # camera z axis in the world
    height = torch.as_tensor(camera_height).to(pos)
    tip = pos - torch.stack([torch.zeros_like(height), torch.zeros_like(height), height])
    axis = rot[..., :, 2]
    slope = (axis * forward).sum(-1)  # depth gained per metre along the axis
    # Deepest drop of a ring below its centre: R |(x_z, y_z)|; the epsilon keeps sqrt smooth.
    rho = torch.sqrt((rot[..., :, 0] * forward).sum(-1) ** 2 + (rot[..., :, 1] * forward).sum(-1) ** 2 + 1e-12)
    margin = (tip * forward).sum(-1) - HAND_PRISM_RADIUS * rho - near  # ring at t keeps margin + t slope >= 0
    safe = torch.where(slope.abs() < 1e-9, torch.full_like(slope, 1e-9), slope)
    crossing = (-margin / safe).clamp(0.0, HAND_LENGTH)
    t0 = torch.where(slope > 0, crossing, torch.zeros_like(crossing))
    t1 = torch.where(slope < 0, crossing, torch.full_like(crossing, HAND_LENGTH))
    visible = (torch.maximum(margin, margin + HAND_LENGTH * slope) > 0) & (t1 - t0 > 1e-6)
    return t0, t1, visible


def prism_planes(vertices: torch.Tensor) -> torch.Tensor:
    """Face planes of convex prisms, normals pointing outwards.

    Args:
        vertices: (..., 2n, 3) prism vertices (rings as in this module).

    Returns:
        (..., n + 2, 4) planes (nx, ny, nz, d): n side faces, then the two caps; a point x is
        inside when n . x <= d for every face. Normals are not unit length; a degenerate
        face has a zero normal.
    """
    n = vertices.shape[-2] // 2
    bottom, top = vertices[..., :n, :], vertices[..., n:, :]
    side = torch.linalg.cross(torch.roll(bottom, -1, dims=-2) - bottom, top - bottom)  # (..., n, 3)
    cap = torch.linalg.cross(bottom[..., 1, :] - bottom[..., 0, :], bottom[..., 2, :] - bottom[..., 0, :])
    normal = torch.cat([side, cap.unsqueeze(-2), cap.unsqueeze(-2)], dim=-2)
    anchor = torch.cat([bottom, bottom[..., :1, :], top[..., :1, :]], dim=-2)  # a point on each face
    centre = vertices.mean(dim=-2, keepdim=True)
    normal = normal * torch.sign(((anchor - centre) * normal).sum(-1, keepdim=True))
    return torch.cat([normal, (normal * anchor).sum(-1, keepdim=True)], dim=-1)


def scene_cuboids(scene) -> tuple:
    """The object and the static cuboids of a per-frame scene, stacked per frame (object first).

    Args:
        scene: any record with ``object_pos`` (N, 3), ``object_rot`` (N, 3, 3),
            ``object_size`` (3,), ``static_pos`` (K, 3), ``static_rot`` (K, 3, 3) and
            ``static_size`` (K, 3), all NumPy arrays or all Torch tensors (a
            :class:`~warpskill.contract.Reconstruction`, a scene of the optimiser).

    Returns:
        cuboid_pos (N, 1 + K, 3) [m], cuboid_rot (N, 1 + K, 3, 3), cuboid_size (1 + K, 3) [m],
        of the inputs' type.
    """
    N, K = len(scene.object_pos), len(scene.static_pos)
    if torch.is_tensor(scene.object_pos):
        return (
            torch.cat([scene.object_pos[:, None], scene.static_pos[None].expand(N, K, 3)], dim=1),
            torch.cat([scene.object_rot[:, None], scene.static_rot[None].expand(N, K, 3, 3)], dim=1),
            torch.cat([scene.object_size[None], scene.static_size], dim=0),
        )
    return (
        np.concatenate([scene.object_pos[:, None], np.broadcast_to(scene.static_pos, (N, K, 3))], axis=1),
        np.concatenate([scene.object_rot[:, None], np.broadcast_to(scene.static_rot, (N, K, 3, 3))], axis=1),
        np.concatenate([scene.object_size[None], scene.static_size], axis=0),
    )
