"""Geometry ``wp.func``s shared by the physics kernels.

All functions are generic over the scalar type (float32 or float64): the type follows the
arguments, and literals are cast with ``type(x)(...)`` so that no float32 constant leaks into
float64 code. Rotations are 3x3 matrices; vectors are column vectors.
"""

from typing import Any

import warp as wp


@wp.func
def _box_distance(q: Any, side: Any):
    """Signed distance and outward normal of a box from per-axis excesses.

    ``q[a]`` is how far the point lies beyond the box's face along axis a (negative inside)
    and ``side[a]`` (+1 or -1) which of the two faces that is. Returns the distance [m] and the
    unit outward normal, both in the box frame.
    """
    zero = type(q[0])(0.0)
    q_max = wp.max(q[0], wp.max(q[1], q[2]))
    axis_x = wp.vector(side[0], zero, zero)
    axis_y = wp.vector(zero, side[1], zero)
    axis_z = wp.vector(zero, zero, side[2])
    d = q_max
    normal = wp.where(q[0] >= q[1] and q[0] >= q[2], axis_x, wp.where(q[1] >= q[2], axis_y, axis_z))
    if q_max > zero:  # outside: distance to the nearest face, edge or corner
        excess = wp.vector(wp.max(q[0], zero), wp.max(q[1], zero), wp.max(q[2], zero))
        d = wp.length(excess)
        normal = wp.cw_mul(excess, side) / d
    return d, normal


@wp.func
def box_sdf(p: Any, half_size: Any):
    """Signed distance [m] (negative inside) and outward unit normal of a point ``p`` against
    the box ``[-half_size, half_size]``; both in the box frame."""
    return _box_distance(wp.abs(p) - half_size, wp.sign(p))


@wp.func
def static_box_sdf(p: Any, half_size: Any):
    """Like :func:`box_sdf` for a box resting on its bottom face: the box is treated as
    extending to -infinity below its top face, so the bottom face never pushes."""
    one = type(p[0])(1.0)
    q = wp.vector(wp.abs(p[0]) - half_size[0], wp.abs(p[1]) - half_size[1], p[2] - half_size[2])
    return _box_distance(q, wp.vector(wp.sign(p[0]), wp.sign(p[1]), one))


@wp.func
def exp_so3(w: Any):
    """Rotation matrix ``Exp(w)`` of a rotation vector ``w`` [rad] by Rodrigues' formula.

    The coefficients sin(t)/t and (1 - cos(t))/t^2 are Taylor series in t^2 (no branch at
    w = 0): relative error below 1e-12 for |w| <= 1 rad and 2e-8 at 2 rad.
    """
    t2 = wp.dot(w, w)
    one = type(t2)(1.0)
    # a = sin(t)/t = sum_k (-t^2)^k / (2k+1)!, Horner form up to t^12
    a = one - t2 / type(t2)(156.0)
    a = one - t2 / type(t2)(110.0) * a
    a = one - t2 / type(t2)(72.0) * a
    a = one - t2 / type(t2)(42.0) * a
    a = one - t2 / type(t2)(20.0) * a
    a = one - t2 / type(t2)(6.0) * a
    # b = (1 - cos(t))/t^2 = sum_k (-t^2)^k / (2k+2)!, Horner form up to t^12
    b = one - t2 / type(t2)(182.0)
    b = one - t2 / type(t2)(132.0) * b
    b = one - t2 / type(t2)(90.0) * b
    b = one - t2 / type(t2)(56.0) * b
    b = one - t2 / type(t2)(30.0) * b
    b = type(t2)(0.5) * (one - t2 / type(t2)(12.0) * b)
    c = one - b * t2
    return wp.diag(wp.vector(c, c, c)) + a * wp.skew(w) + b * wp.outer(w, w)


@wp.func
def orthonormalize(m: Any):
    """Gram-Schmidt re-orthonormalisation of the columns of ``m``: the first normalised, the
    second made orthogonal to it and normalised, the third their cross product."""
    c0 = wp.normalize(wp.vector(m[0, 0], m[1, 0], m[2, 0]))
    c1 = wp.vector(m[0, 1], m[1, 1], m[2, 1])
    c1 = wp.normalize(c1 - wp.dot(c0, c1) * c0)
    return wp.matrix_from_cols(c0, c1, wp.cross(c0, c1))
