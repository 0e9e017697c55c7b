"""The physics kernels' records (Warp structs), made per scalar type (float32 or float64) by :func:`records`.

``Physics``: the constants ``dt`` [s], ``kp`` [1/s^2], ``kv`` [1/s], ``mu`` [1/s], ``gravity`` [m/s^2],
``free_damping`` [1/s], ``grasp_decay`` [1/s] and ``grasp_tau`` [m] (``warpskill.engine.simulation.PhysicsConfig``).
``Scene``: the rollout's inputs, arrays of B scenes named as ``warpskill.engine.records.SceneInputs``'s fields:
``hand_pos0``, ``hand_rot0``, ``grasp0``, ``hand_vel`` (B, S, 7) = v_h, w_h, grasp rate, ``object_pos0``,
``object_rot0``, ``object_size`` (B,) and ``static_pos``, ``static_rot``, ``static_size`` (B, K).
``Trajectory``: arrays (B, T) of B scenes over T states (steps or frames): ``hand_pos``, ``object_pos``, the
object's total velocities ``object_vel`` [m/s], ``object_ang_vel`` [rad/s] (vec3); ``hand_rot``, ``object_rot``
(mat33); ``grasp``, ``grasped`` (switch s), ``tip_distance`` [m] (scalars).
``Scratch``: arrays (B, T) of vec3 the rollout works in: the object's own velocities ``own_vel`` [m/s],
``own_ang_vel`` [rad/s] per state (T = S + 1) and the contact impulse sums ``impulse_v`` [m/s^2], ``impulse_w``
[rad/s^2] per step (T = S), accumulated into.

Gradients flow through a struct's arrays' own ``grad`` arrays (Warp's adjoint of an array read through a struct).
"""

import functools
from typing import NamedTuple

import warp as wp


class Records(NamedTuple):
    """The struct types of one scalar type."""

    Physics: type
    Scene: type
    Trajectory: type
    Scratch: type


@functools.cache
def records(dtype) -> Records:
    """The physics kernels' struct types for scalar type ``dtype`` (``wp.float32`` or ``wp.float64``)."""
    vec3, mat33 = wp.types.vector(3, dtype), wp.types.matrix((3, 3), dtype)

    @wp.struct
    class Physics:
        dt: dtype
        kp: dtype
        kv: dtype
        mu: dtype
        gravity: dtype
        free_damping: dtype
        grasp_decay: dtype
        grasp_tau: dtype

    @wp.struct
    class Scene:
        hand_pos0: wp.array(dtype=vec3)
        hand_rot0: wp.array(dtype=mat33)
        grasp0: wp.array(dtype=dtype)
        hand_vel: wp.array3d(dtype=dtype)
        object_pos0: wp.array(dtype=vec3)
        object_rot0: wp.array(dtype=mat33)
        object_size: wp.array(dtype=vec3)
        static_pos: wp.array2d(dtype=vec3)
        static_rot: wp.array2d(dtype=mat33)
        static_size: wp.array2d(dtype=vec3)

    @wp.struct
    class Trajectory:
        hand_pos: wp.array2d(dtype=vec3)
        hand_rot: wp.array2d(dtype=mat33)
        grasp: wp.array2d(dtype=dtype)
        grasped: wp.array2d(dtype=dtype)
        tip_distance: wp.array2d(dtype=dtype)
        object_pos: wp.array2d(dtype=vec3)
        object_rot: wp.array2d(dtype=mat33)
        object_vel: wp.array2d(dtype=vec3)
        object_ang_vel: wp.array2d(dtype=vec3)

    @wp.struct
    class Scratch:
        own_vel: wp.array2d(dtype=vec3)
        own_ang_vel: wp.array2d(dtype=vec3)
        impulse_v: wp.array2d(dtype=vec3)
        impulse_w: wp.array2d(dtype=vec3)

    return Records(Physics, Scene, Trajectory, Scratch)


def zeros(kind, shapes: dict, device, requires_grad: bool):
    """An instance of the struct type ``kind`` (of :func:`records`) whose arrays are zeroed, of the ``shapes`` by
    field name, on ``device``, with gradients if ``requires_grad``."""
    record = kind()
    for name, var in kind.vars.items():
        array = wp.zeros(shapes[name], dtype=var.type.dtype, device=device, requires_grad=requires_grad)
        setattr(record, name, array)
    return record

