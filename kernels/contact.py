"""SDF point-impulse contact of the manipulated cuboid, and the hand tip's signed distance.

The manipulated cuboid carries ``NUM_SAMPLE_POINTS`` = 62 sample points: the full 5 x 5 grids
of its bottom and top faces and the 3 interior points of each of its 4 vertical edges. Each
point pushes against the ground z = 0 and against every static cuboid (top and side faces;
the bottom face lies on the ground and does not push):

    m = max(-kp d - kv min(v . n, 0), 0)
    j = m n - 1(m > 0) mu (v - (v . n) n)
    j_v = sum j,   j_w = sum q x j

Impulses act as accelerations (unit mass and inertia): [m/s^2] and [rad/s^2].
"""

import functools
from typing import Any

import warp as wp

from .geometry import box_sdf, static_box_sdf
from .records import records

NUM_SAMPLE_POINTS = 62


@wp.func
def _sample_point(i: int, size: Any):
    """Offset [m] of sample point ``i`` (0..61) from the centre of a cuboid of full edge
    lengths ``size``, in the cuboid's frame."""
    # 0..24 bottom face, 25..49 top face: 5 x 5 grids
    gx = i % 5
    gy = (i // 5) % 5
    gz = (i // 25) * 4
    if i >= 50:  # 50..61: 3 interior points on each vertical edge
        gx = ((i - 50) // 3) % 2 * 4
        gy = ((i - 50) // 6) * 4
        gz = (i - 50) % 3 + 1
    quarter = type(size[0])(0.25)
    half = type(size[0])(0.5)
    unit = wp.vector(
        type(size[0])(gx) * quarter - half,
        type(size[0])(gy) * quarter - half,
        type(size[0])(gz) * quarter - half,
    )
    return wp.cw_mul(unit, size)


@wp.func
def _point_impulse(kp: Any, kv: Any, mu: Any, d: Any, normal: Any, v: Any):
    """Impulse [m/s^2] on a point at signed distance ``d`` [m] from an obstacle with outward
    normal ``normal``, moving with velocity ``v`` [m/s]."""
    zero = type(d)(0.0)
    vn = wp.dot(v, normal)
    m = wp.max(-kp * d - kv * wp.min(vn, zero), zero)
    j = v * zero
    if m > zero:
        j = m * normal - mu * (v - vn * normal)
    return j


@functools.cache
def contact_impulses_func(dtype):
    """The ``wp.func`` ``add_contact_impulses`` for scalar type ``dtype`` (float32 or float64).

    ``add_contact_impulses(physics, mu, scene, object_size, object_pos, object_rot, object_vel, object_ang_vel,
    lane, lanes, b, n, scratch)`` adds the contact impulses j_v [m/s^2] and j_w [rad/s^2] of sample points
    ``lane``, ``lane + lanes``, ... on the cuboid of size ``object_size`` of scene ``b`` (its statics in ``scene``,
    :mod:`.records`) at pose (``object_pos``, ``object_rot``), moving with total velocities ``object_vel`` [m/s] and
    ``object_ang_vel`` [rad/s], with ``physics``'s kp and kv and friction ``mu``, to ``scratch.impulse_v[b, n]`` and
    ``scratch.impulse_w[b, n]``: ``lanes`` threads with lanes 0, 1, ... add all of them.

    It sums with ``wp.atomic_add`` and keeps no loop-carried locals, so its adjoint is exact
    inside a dynamic loop. Its replay (the forward pass re-run during backward) does nothing:
    replaying the atomic adds would double the sums that the caller reads afterwards.
    """
    vec3 = wp.types.vector(3, dtype)
    mat33 = wp.types.matrix((3, 3), dtype)
    Physics, Scene, _, Scratch = records(dtype)

    @wp.func
    def add_contact_impulses(physics: Physics, mu: dtype, scene: Scene, object_size: vec3, object_pos: vec3,
                             object_rot: mat33, object_vel: vec3, object_ang_vel: vec3, lane: int, lanes: int, b: int,
                             n: int, scratch: Scratch):
        kp, kv = physics.kp, physics.kv
        # An obstacle farther from the centre than the bounding radius plus the reach of the
        # damping term pushes no point (m = 0 for all): skipping it changes neither the
        # impulses nor their gradients. The radius has 1% slack for rotations that are not
        # exactly orthonormal (finite-difference perturbations of their entries).
        radius = dtype(0.505) * wp.length(object_size)
        damping_reach = kv / kp * (wp.length(object_vel) + wp.length(object_ang_vel) * radius)
        reach = radius + damping_reach
        # Likewise a sample point higher than the damping term's reach (with 1 % and 1 um of
        # slack for rounding) pushes nothing: most of a resting cuboid's points are skipped.
        point_reach = dtype(1.01) * damping_reach + dtype(1.0e-6)
        up = vec3(dtype(0.0), dtype(0.0), dtype(1.0))
        if object_pos[2] <= reach:
            for i in range(lane, NUM_SAMPLE_POINTS, lanes):
                offset = _sample_point(i, object_size)
                height = object_pos[2] + wp.dot(vec3(object_rot[2, 0], object_rot[2, 1], object_rot[2, 2]), offset)
                if height <= point_reach:
                    q = object_rot * offset
                    v = object_vel + wp.cross(object_ang_vel, q)
                    j_ground = _point_impulse(kp, kv, mu, object_pos[2] + q[2], up, v)
                    wp.atomic_add(scratch.impulse_v, b, n, j_ground)
                    wp.atomic_add(scratch.impulse_w, b, n, wp.cross(q, j_ground))
        for k in range(scene.static_pos.shape[1]):
            rot = scene.static_rot[b, k]
            half = dtype(0.5) * scene.static_size[b, k]
            offset = wp.transpose(rot) * (object_pos - scene.static_pos[b, k])  # the centre, static frame
            d_centre, _ = static_box_sdf(offset, half)
            if d_centre <= reach:
                for i in range(lane, NUM_SAMPLE_POINTS, lanes):
                    q = object_rot * _sample_point(i, object_size)
                    v = object_vel + wp.cross(object_ang_vel, q)
                    d, normal = static_box_sdf(offset + wp.transpose(rot) * q, half)
                    j_static = _point_impulse(kp, kv, mu, d, rot * normal, v)
                    wp.atomic_add(scratch.impulse_v, b, n, j_static)
                    wp.atomic_add(scratch.impulse_w, b, n, wp.cross(q, j_static))

    # Warp requires the replay to repeat the signature; the sums are already in place.
    @wp.func_replay(add_contact_impulses)
    def _replay(physics: Physics, mu: dtype, scene: Scene, object_size: vec3, object_pos: vec3, object_rot: mat33,
                object_vel: vec3, object_ang_vel: vec3, lane: int, lanes: int, b: int, n: int, scratch: Scratch):
        pass

    return add_contact_impulses


@wp.func
def tip_distance(hand_pos: Any, object_pos: Any, object_rot: Any, object_size: Any):
    """Signed distance [m] of the hand tip from the cuboid's surface (negative inside)."""
    d, _ = box_sdf(wp.transpose(object_rot) * (hand_pos - object_pos), type(hand_pos[0])(0.5) * object_size)
    return d


@functools.cache
def _kernels(dtype):
    """The test kernels for scalar type ``dtype`` (``wp.float32`` or ``wp.float64``)."""
    vec3 = wp.types.vector(3, dtype)
    mat33 = wp.types.matrix((3, 3), dtype)
    Physics, Scene, _, Scratch = records(dtype)
    add_contact_impulses = contact_impulses_func(dtype)

    @wp.kernel(module="unique")
    def _contact_impulses(
        # Model:
        physics: Physics,
        # Data in:
        scene: Scene,
        lanes: int,
        # Data in and out:
        scratch: Scratch,
    ):
        b, lane = wp.tid()
        add_contact_impulses(physics, physics.mu, scene, scene.object_size[b], scene.object_pos0[b],
                             scene.object_rot0[b], scratch.own_vel[b, 0], scratch.own_ang_vel[b, 0], lane, lanes, b,
                             0, scratch)

    @wp.kernel(module="unique")
    def _tip_distance(
        # Model:
        object_size_in: wp.array(dtype=vec3),
        # Data in:
        hand_pos_in: wp.array(dtype=vec3),
        object_pos_in: wp.array(dtype=vec3),
        object_rot_in: wp.array(dtype=mat33),
        # Data out:
        distance_out: wp.array(dtype=dtype),
    ):
        b = wp.tid()
        distance_out[b] = tip_distance(hand_pos_in[b], object_pos_in[b], object_rot_in[b], object_size_in[b])

    return _contact_impulses, _tip_distance


def contact_impulses(physics, scene, scratch, lanes: int = 1):
    """Contact impulses of the B cuboids of ``scene`` (:mod:`.records`) at their initial poses, moving with the
    velocities ``scratch.own_vel``, ``scratch.own_ang_vel`` [:, 0], into ``scratch.impulse_v``, ``impulse_w``
    [:, 0] (zeroed first), by ``lanes`` threads per cuboid (each its share of the sample points)."""
    scratch.impulse_v.zero_()
    scratch.impulse_w.zero_()
    kernel = _kernels(scene.object_size.dtype._wp_scalar_type_)[0]
    wp.launch(kernel, dim=(scene.object_size.shape[0], lanes), inputs=[physics, scene, lanes], outputs=[scratch],
              device=scene.object_size.device)


def hand_tip_distance(
    object_size: wp.array, hand_pos: wp.array, object_pos: wp.array, object_rot: wp.array, distance_out: wp.array
):
    """Signed distance [m] of B hand tips to their cuboids (arrays (B,)) into ``distance_out``."""
    wp.launch(
        _kernels(object_pos.dtype._wp_scalar_type_)[1],
        dim=object_pos.shape[0],
        inputs=[object_size, hand_pos, object_pos, object_rot],
        outputs=[distance_out],
        device=object_pos.device,
    )
