"""The soft silhouettes of ``warpskill.engine.rendering.render_silhouettes`` in plain PyTorch (autograd).

Dense: every pixel against every hull edge and face of every primitive, no tiles, no screen
bounds, no hand-written backward. Per frame f, primitive k and pixel centre p:

    hull edges    the ordered vertex pairs (i, j) whose line has every vertex of the prism
                  behind it (a supporting line of a convex polygon is a hull edge)
    sd_k(p)       max over hull edges of n . p - o  [px] (n outward, unit)
    c_k           sigmoid(-sd_k / sigma), exactly 0 beyond sd = CUTOFF sigma, 1 below -CUTOFF sigma
    z_k           entry depth [m] of the ray through p (max over camera-facing planes with
                  n . r < 0 of d / n . r); outside the hull, of the ray through the nearest
                  hull point
    v_k           c_k prod_{l: z_l < z_k} (1 - c_l), ties to the lower index

Depth order and the choice of the edge that holds sd carry no gradient (as in the kernels);
sd itself is differentiated through the projected vertices. Vertices, near-plane clipping
and projection are the shared Torch functions of :mod:`warpskill.engine.primitives` and
:mod:`warpskill.engine.projection`.

Unlike the kernels, no pixel is skipped for lying outside a primitive's padded screen
bounds; the bounds hold every pixel of nonzero coverage except beyond corners sharper
than about 29 degrees, where the coverage the kernels drop is below 1e-4.
"""

from __future__ import annotations

import torch

from warpskill.contract.camera import Intrinsics
from warpskill.engine.primitives import (
    NEAR_PLANE,
    cuboid_vertices,
    hand_axis_extent,
    hand_vertices,
    prism_planes,
)
from warpskill.engine.projection import project, world_to_camera
from warpskill.engine.rendering import check_silhouette_inputs
from warpskill.kernels.raster import CUTOFF

_CHUNK_ELEMENTS = 2**24  # elements of the largest per-pixel temporary (per frame chunk)


def render_reference(
    hand_pos: torch.Tensor,
    hand_rot: torch.Tensor,
    cuboid_pos: torch.Tensor,
    cuboid_rot: torch.Tensor,
    cuboid_size: torch.Tensor,
    camera_height: torch.Tensor,
    camera_elevation: torch.Tensor,
    intrinsics: Intrinsics,
    *,
    sigma: float = 1.0,
) -> torch.Tensor:
    """Soft visible masks of the hand and the cuboids, as :func:`warpskill.engine.rendering.render_silhouettes`
    (same arguments, same checks), computed in the dtype of ``hand_pos``.

    Args:
        hand_pos: (F, 3) hand tip positions [m].
        hand_rot: (F, 3, 3) hand rotations.
        cuboid_pos: (F, C, 3) cuboid centres [m], C >= 0.
        cuboid_rot: (F, C, 3, 3) cuboid rotations.
        cuboid_size: (C, 3) or (F, C, 3) cuboid edge lengths [m].
        camera_height: scalar camera height [m].
        camera_elevation: scalar camera elevation [rad].
        intrinsics: camera intrinsics; ``intrinsics.image_size`` (H, W) is the output size.
        sigma: edge softness [px].

    Returns:
        (F, 1 + C, H, W) visible masks in [0, 1]: channel 0 the hand, then the cuboids.
    """
    check_silhouette_inputs(
        hand_pos, hand_rot, cuboid_pos, cuboid_rot, cuboid_size, camera_height, camera_elevation, intrinsics, sigma
    )
    dtype = hand_pos.dtype
    F, C = cuboid_pos.shape[:2]
    H, W = intrinsics.image_size
    t0, t1, hand_visible = hand_axis_extent(hand_pos, hand_rot, camera_height, camera_elevation)
    hand = world_to_camera(hand_vertices(hand_pos, hand_rot, extent=(t0, t1)), camera_height, camera_elevation)
    cuboids = world_to_camera(
        cuboid_vertices(cuboid_pos.to(dtype), cuboid_rot.to(dtype), cuboid_size.to(dtype).expand(F, C, 3)),
        camera_height,
        camera_elevation,
    )
    K = torch.as_tensor(intrinsics.K, dtype=dtype, device=hand_pos.device)
    v, u = torch.meshgrid(torch.arange(H), torch.arange(W), indexing="ij")
    pixels = (torch.stack([u, v], -1).reshape(-1, 2) + 0.5).to(hand_pos)  # (HW, 2) pixel centres
    groups = [_soft_layers(hand.unsqueeze(1), hand_visible.unsqueeze(1), K, pixels, sigma)]
    if C:
        groups.append(_soft_layers(cuboids, (cuboids[..., 2] >= NEAR_PLANE).all(-1), K, pixels, sigma))
    coverage = torch.cat([c for c, _ in groups], 1)
    depth = torch.cat([z for _, z in groups], 1)
    return _composite(coverage, depth).reshape(F, 1 + C, H, W)


def _soft_layers(
    vertices: torch.Tensor, visible: torch.Tensor, K: torch.Tensor, pixels: torch.Tensor, sigma: float
) -> tuple[torch.Tensor, torch.Tensor]:
    """Coverage (F, P, HW) and depth [m] (F, P, HW, no gradient) of prisms at every pixel.

    Args:
        vertices: (F, P, V, 3) camera-frame prism vertices [m].
        visible: (F, P) bool, False for prisms cut by the near plane.
        K: (3, 3) intrinsics [px].
        pixels: (HW, 2) pixel centres [px].
        sigma: edge softness [px].
    """
    image = project(vertices, K)  # (F, P, V, 2)
    normal, offset, start, end, used = _hull_edges(image)
    drawn = visible & (used.sum(-1) >= 3)
    planes = prism_planes(vertices.detach())
    with torch.no_grad():
        edge, depth = _edge_and_depth(normal, offset, start, end, used, planes, K, pixels)
    n = torch.gather(normal, 2, edge.unsqueeze(-1).expand(*edge.shape, 2))  # (F, P, HW, 2)
    sd = (n * pixels).sum(-1) - torch.gather(offset, 2, edge)
    limit = CUTOFF * sigma
    soft = torch.sigmoid(-sd / sigma)
    coverage = torch.where(sd > limit, torch.zeros_like(sd), torch.where(sd < -limit, torch.ones_like(sd), soft))
    return coverage * drawn.unsqueeze(-1), depth


def _hull_edges(image: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """The hull edges of projected prisms: every ordered vertex pair whose line supports the
    vertex set, compacted into E slots.

    Args:
        image: (F, P, V, 2) projected vertices [px].

    Returns:
        normal (F, P, E, 2) unit outward normals, offset (F, P, E) with n . p - offset the
        signed distance [px] from the edge's line, start and end (F, P, E, 2) its vertices
        [px], and used (F, P, E) bool marking the slots that hold an edge.
    """
    F, P, V, _ = image.shape
    start = image.unsqueeze(3).expand(F, P, V, V, 2)  # pair (i, j): from vertex i to vertex j
    end = image.unsqueeze(2).expand(F, P, V, V, 2)
    d = end - start
    length = torch.linalg.vector_norm(d, dim=-1)
    normal = torch.stack([d[..., 1], -d[..., 0]], -1) / length.clamp_min(1e-12).unsqueeze(-1)
    offset = (normal * start).sum(-1)
    with torch.no_grad():
        extent = torch.linalg.vector_norm(image.amax(-2) - image.amin(-2), dim=-1)[..., None, None]
        tolerance = 8 * torch.finfo(image.dtype).eps * extent  # roundoff of n . (q - a) [px]
        beyond = torch.einsum("fpijc,fpqc->fpijq", normal, image) - (normal * start).sum(-1, keepdim=True)
        reach = beyond.amax(-1)  # how far the farthest vertex lies beyond the line (i, j)
        supporting = (reach <= tolerance) & (length > tolerance)
        supporting = supporting.reshape(F, P, V * V)
        count = supporting.sum(-1)
        slots = int(count.max()) if count.numel() else 0
        order = torch.argsort((~supporting).to(torch.int8), dim=-1, stable=True)[..., :slots]
        used = torch.arange(slots, device=image.device) < count.unsqueeze(-1)

    def pick(x: torch.Tensor) -> torch.Tensor:
        flat = x.reshape(F, P, V * V, *x.shape[4:])
        index = order.reshape(*order.shape, *([1] * (flat.dim() - 3))).expand(*order.shape, *flat.shape[3:])
        return torch.gather(flat, 2, index)

    return pick(normal), pick(offset), pick(start), pick(end), used


def _edge_and_depth(normal, offset, start, end, used, planes, K, pixels) -> tuple[torch.Tensor, torch.Tensor]:
    """Per pixel: the hull edge that holds the signed distance (F, P, HW) and the depth [m]
    (F, P, HW), in frame chunks that bound the temporaries. Arguments as returned by
    :func:`_hull_edges`; planes (F, P, n + 2, 4) in camera coordinates."""
    F, P, E = used.shape
    chunk = max(1, _CHUNK_ELEMENTS // max(1, P * max(E, planes.shape[2]) * len(pixels)))
    edges, depths = [], []
    for f in range(0, F, chunk):
        part = slice(f, f + chunk)
        lines = torch.einsum("fpec,xc->fpex", normal[part], pixels) - offset[part].unsqueeze(-1)
        lines = torch.where(used[part].unsqueeze(-1), lines, -torch.inf)
        sd, edge = lines.max(dim=2)
        nearest = _nearest_hull_point(start[part], end[part], used[part], pixels)
        target = torch.where((sd > 0).unsqueeze(-1), nearest, pixels)  # (f, P, HW, 2)
        edges.append(edge)
        depths.append(_entry_depth(planes[part], K, target))
    return torch.cat(edges), torch.cat(depths)


def _nearest_hull_point(start, end, used, pixels) -> torch.Tensor:
    """Nearest point (F, P, HW, 2) [px] of the hull boundary to every pixel centre."""
    d = (end - start).unsqueeze(-2)  # (F, P, E, 1, 2)
    rel = pixels - start.unsqueeze(-2)  # (F, P, E, HW, 2)
    t = ((rel * d).sum(-1) / (d * d).sum(-1).clamp_min(1e-12)).clamp(0.0, 1.0)
    foot = start.unsqueeze(-2) + t.unsqueeze(-1) * d
    distance = torch.where(used.unsqueeze(-1), ((pixels - foot) ** 2).sum(-1), torch.inf)
    closest = distance.argmin(dim=2, keepdim=True)  # (F, P, 1, HW)
    return torch.gather(foot, 2, closest.unsqueeze(-1).expand(-1, -1, -1, -1, 2)).squeeze(2)


def _entry_depth(planes: torch.Tensor, K: torch.Tensor, points: torch.Tensor) -> torch.Tensor:
    """Entry depth [m] (F, P, HW) of the rays through image points (F, P, HW, 2) [px] into
    prisms bounded by planes (F, P, n + 2, 4): the max over the camera-facing faces (d < 0)
    that the ray enters (n . r < 0) of d / n . r; -inf where there is none."""
    ray = torch.stack(
        [(points[..., 0] - K[0, 2]) / K[0, 0], (points[..., 1] - K[1, 2]) / K[1, 1], torch.ones_like(points[..., 0])],
        -1,
    )
    nr = torch.einsum("fpnc,fpxc->fpnx", planes[..., :3], ray)
    enters = (nr < 0) & (planes[..., 3:] < 0)
    return torch.where(enters, planes[..., 3:] / nr, -torch.inf).amax(dim=2)


def _composite(coverage: torch.Tensor, depth: torch.Tensor) -> torch.Tensor:
    """Visible masks v_k = c_k prod_{l in front of k} (1 - c_l) from coverage and depth (F, P, HW)."""
    P = coverage.shape[1]
    index = torch.arange(P, device=coverage.device).view(1, P, 1)
    transmittance = torch.ones_like(coverage)
    for l in range(P):
        z = depth[:, l : l + 1]
        in_front = (z < depth) | ((z == depth) & (l < index))  # layer l in front of each layer k
        transmittance = transmittance * torch.where(in_front, 1.0 - coverage[:, l : l + 1], 1.0)
    return coverage * transmittance
