"""Rigid-body geometry in plain Torch, batched over leading dimensions: box signed distances,
the rotation exponential and Gram-Schmidt re-orthonormalisation.

Every function is differentiable by autograd, including at the zero rotation and on the
box's faces (one-sided there, as a max is).
"""

from __future__ import annotations

import torch

_SERIES_LIMIT = 1e-6  # |w|^2 [rad^2] below which Exp uses its Taylor coefficients


def _signs(x: torch.Tensor) -> torch.Tensor:
    """-1 where x < 0, else +1 (a point on a mid-plane belongs to the positive side)."""
    return torch.where(x < 0, -torch.ones_like(x), torch.ones_like(x))


def _excess_distance(excess: torch.Tensor, side: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Signed distance (...) and outward unit normal (..., 3) from per-axis excesses.

    ``excess[..., a]`` is how far the point lies beyond the face on axis a (negative inside),
    ``side[..., a]`` (+-1) which face of that axis it is. Inside, the nearest face (ties
    to the lower axis) holds the distance; outside, the Euclidean distance to the box.
    """
    deepest, axis = excess.max(dim=-1)
    inside_normal = torch.nn.functional.one_hot(axis, 3).to(excess) * side
    outside = deepest > 0
    beyond = excess.clamp_min(0.0)
    squared = torch.where(outside, (beyond * beyond).sum(-1), torch.ones_like(deepest))  # no sqrt'(0)
    length = squared.sqrt()
    distance = torch.where(outside, length, deepest)
    normal = torch.where(outside.unsqueeze(-1), beyond * side / length.unsqueeze(-1), inside_normal)
    return distance, normal


def box_distance(p: torch.Tensor, half_size: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Signed distance [m] (negative inside) and outward unit normal of points ``p`` (..., 3)
    against boxes ``[-half_size, half_size]`` (..., 3), both in the box frame."""
    return _excess_distance(p.abs() - half_size, _signs(p))


def resting_box_distance(p: torch.Tensor, half_size: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Like :func:`box_distance` for a box resting on its bottom face: the box extends to
    z = -infinity, so its bottom face never holds the distance."""
    excess = torch.cat([p[..., :2].abs() - half_size[..., :2], p[..., 2:] - half_size[..., 2:]], dim=-1)
    side = torch.cat([_signs(p[..., :2]), torch.ones_like(p[..., 2:])], dim=-1)
    return _excess_distance(excess, side)


def skew(w: torch.Tensor) -> torch.Tensor:
    """Cross-product matrices (..., 3, 3) of vectors w (..., 3): skew(w) x = w x x."""
    zero = torch.zeros_like(w[..., 0])
    x, y, z = w.unbind(-1)
    return torch.stack(
        [torch.stack([zero, -z, y], -1), torch.stack([z, zero, -x], -1), torch.stack([-y, x, zero], -1)], -2
    )


def exp_rotation(w: torch.Tensor) -> torch.Tensor:
    """Rotation matrices Exp(w) (..., 3, 3) of rotation vectors w (..., 3) [rad].

    Rodrigues: I + a skew(w) + b skew(w)^2 with t = |w|, a = sin(t)/t and
    b = (1 - cos t)/t^2 = 2 (sin(t/2)/t)^2 (the half-angle form has no cancellation in
    float32); below t^2 = 1e-6 both come from their Taylor series.
    """
    t2 = (w * w).sum(-1)
    small = t2 < _SERIES_LIMIT
    t = torch.where(small, torch.ones_like(t2), t2).sqrt()
    half_sinc = torch.sin(0.5 * t) / t
    a = torch.where(small, 1.0 - t2 / 6.0 + t2 * t2 / 120.0, torch.sin(t) / t)
    b = torch.where(small, 0.5 - t2 / 24.0 + t2 * t2 / 720.0, 2.0 * half_sinc * half_sinc)
    k = skew(w)
    eye = torch.eye(3, dtype=w.dtype, device=w.device)
    return eye + a[..., None, None] * k + b[..., None, None] * (k @ k)


def orthonormalize(m: torch.Tensor) -> torch.Tensor:
    """Gram-Schmidt on the columns of m (..., 3, 3): the first normalised, the second made
    orthogonal to it and normalised, the third their cross product."""
    first = torch.nn.functional.normalize(m[..., :, 0], dim=-1)
    second = m[..., :, 1] - (first * m[..., :, 1]).sum(-1, keepdim=True) * first
    second = torch.nn.functional.normalize(second, dim=-1)
    return torch.stack([first, second, torch.linalg.cross(first, second)], dim=-1)
