"""Whole-rollout semi-implicit integrator: a block of threads per scene, a dynamic loop over steps.

Step n reads state n from per-step arrays (B, S + 1) and writes state n + 1; nothing is
carried across iterations in locals, so Warp's reverse pass replays every step exactly. The
block's threads (lanes) share the contact sample points of a step; its first lane integrates
and writes the states, and a block barrier separates each step's writes from the next reads
(:func:`rollout` picks one lane on the CPU, :data:`CUDA_LANES` on a GPU). Per step, with
r = x_o - x_h and s the latched grasp switch (1 = grasped; :func:`_grasp_switch`):

    ds = s_n - s_{n-1}  (s_{-1} = s_0)
    v_o += max(ds, 0) (-v_o) + max(-ds, 0) (v_h + w_h x r),   w_o likewise with w_h
    (j_v, j_w) = contact at the current pose, total velocities s (v_h + w_h x r) + v_o, s w_h + w_o,
                 with friction (1 - s) mu: a firm grip dominates ground friction
    v_o' = v_o + dt (j_v - s k_g v_o + (1 - s) (gravity - c v_o))
    w_o' = w_o + dt (j_w - s k_g w_o - (1 - s) c w_o)
    x_h' = x_h + dt v_h,   R_h' = Exp(dt w_h) R_h,   g' = g + dt g_rate
    x_o' = x_o + s (x_h' + Exp(dt w_h) r - x_o) + dt v_o'
    R_o' = orthonormalize(Exp(dt w_o') Exp(s dt w_h) R_o)

v_o, w_o are the object's own velocities (total when free, residual impulse velocity when
grasped). The total velocities reported at state n + 1 are those of step n:
s_n (v_h + w_h x r) + v_o' and s_n w_h + w_o' (at state 0: s_0 (v_h + w_h x r), s_0 w_h).
"""

import dataclasses
import functools
from typing import Any

import warp as wp

from . import OPTIMIZATION_LEVEL
from .contact import contact_impulses_func, tip_distance
from .geometry import exp_so3, orthonormalize

CUDA_LANES = 32
"""Threads per scene on a GPU: one warp, about two of the 62 contact sample points each."""


@wp.func_native(snippet="WP_TILE_SYNC();", adj_snippet="WP_TILE_SYNC();")
def _block_barrier():
    """Wait for every thread of the block (also in the reverse pass): writes before it are seen after it."""
    ...


@wp.func
def _sigmoid(x: Any):
    """Overflow-free logistic function."""
    one = type(x)(1.0)
    e = wp.exp(-wp.abs(x))
    return wp.where(x >= type(x)(0.0), one / (one + e), e / (one + e))


@wp.func
def _grasp_switch(tip_distance: Any, grasp: Any, held: Any, tau: Any):
    """Latched grasp state min(sigmoid(grasp / tau), max(held, sigmoid(-tip_distance / tau))) in
    [0, 1] (1 = grasped), ``held`` the previous state (0 at the start)."""
    return wp.min(_sigmoid(grasp / tau), wp.max(held, _sigmoid(-tip_distance / tau)))


@functools.cache
def _kernels(dtype):
    """The rollout and frame-gather kernels for scalar type ``dtype``."""
    vec3 = wp.types.vector(3, dtype)
    mat33 = wp.types.matrix((3, 3), dtype)
    add_contact_impulses = contact_impulses_func(dtype)

    @wp.kernel(module="unique", module_options={"optimization_level": OPTIMIZATION_LEVEL})
    def _rollout(
        # Model:
        dt: dtype,
        kp: dtype,
        kv: dtype,
        mu: dtype,
        gravity: dtype,
        free_damping: dtype,
        grasp_decay: dtype,
        grasp_tau: dtype,
        object_size_in: wp.array(dtype=vec3),
        static_pos_in: wp.array2d(dtype=vec3),
        static_rot_in: wp.array2d(dtype=mat33),
        static_size_in: wp.array2d(dtype=vec3),
        # Data in:
        hand_pos0_in: wp.array(dtype=vec3),
        hand_rot0_in: wp.array(dtype=mat33),
        grasp0_in: wp.array(dtype=dtype),
        hand_vel_in: wp.array3d(dtype=dtype),
        object_pos0_in: wp.array(dtype=vec3),
        object_rot0_in: wp.array(dtype=mat33),
        # Data out (per step, S + 1 states; impulses S steps):
        hand_pos_out: wp.array2d(dtype=vec3),
        hand_rot_out: wp.array2d(dtype=mat33),
        grasp_out: wp.array2d(dtype=dtype),
        grasped_out: wp.array2d(dtype=dtype),
        tip_distance_out: wp.array2d(dtype=dtype),
        object_pos_out: wp.array2d(dtype=vec3),
        object_rot_out: wp.array2d(dtype=mat33),
        object_own_vel_out: wp.array2d(dtype=vec3),
        object_own_ang_vel_out: wp.array2d(dtype=vec3),
        object_vel_out: wp.array2d(dtype=vec3),
        object_ang_vel_out: wp.array2d(dtype=vec3),
        impulse_v_out: wp.array2d(dtype=vec3),
        impulse_w_out: wp.array2d(dtype=vec3),
    ):
        b, lane = wp.tid()
        lanes = wp.block_dim()
        zero = dtype(0.0)
        one = dtype(1.0)
        size = object_size_in[b]
        fall = vec3(zero, zero, -gravity)

        if lane == 0:  # state 0: the object at rest (own velocities zero)
            d0 = tip_distance(hand_pos0_in[b], object_pos0_in[b], object_rot0_in[b], size)
            s0 = _grasp_switch(d0, grasp0_in[b], zero, grasp_tau)
            v_h0 = vec3(hand_vel_in[b, 0, 0], hand_vel_in[b, 0, 1], hand_vel_in[b, 0, 2])
            w_h0 = vec3(hand_vel_in[b, 0, 3], hand_vel_in[b, 0, 4], hand_vel_in[b, 0, 5])
            hand_pos_out[b, 0] = hand_pos0_in[b]
            hand_rot_out[b, 0] = hand_rot0_in[b]
            grasp_out[b, 0] = grasp0_in[b]
            grasped_out[b, 0] = s0
            tip_distance_out[b, 0] = d0
            object_pos_out[b, 0] = object_pos0_in[b]
            object_rot_out[b, 0] = object_rot0_in[b]
            object_own_vel_out[b, 0] = vec3(zero, zero, zero)
            object_own_ang_vel_out[b, 0] = vec3(zero, zero, zero)
            object_vel_out[b, 0] = s0 * (v_h0 + wp.cross(w_h0, object_pos0_in[b] - hand_pos0_in[b]))
            object_ang_vel_out[b, 0] = s0 * w_h0

        for n in range(hand_vel_in.shape[1]):
            _block_barrier()  # state n, written by lane 0, is seen by every lane
            x_h = hand_pos_out[b, n]
            x_o = object_pos_out[b, n]
            rot_o = object_rot_out[b, n]
            s = grasped_out[b, n]
            ds = s - grasped_out[b, wp.max(n - 1, 0)]
            v_h = vec3(hand_vel_in[b, n, 0], hand_vel_in[b, n, 1], hand_vel_in[b, n, 2])
            w_h = vec3(hand_vel_in[b, n, 3], hand_vel_in[b, n, 4], hand_vel_in[b, n, 5])
            r = x_o - x_h
            v_carry = v_h + wp.cross(w_h, r)

            # grasp event zeroes the own velocity, release hands over the hand's
            grasp_event = wp.max(ds, zero)
            release_event = wp.max(-ds, zero)
            v_o = object_own_vel_out[b, n]
            w_o = object_own_ang_vel_out[b, n]
            v_e = v_o - grasp_event * v_o + release_event * v_carry
            w_e = w_o - grasp_event * w_o + release_event * w_h

            # a firm grip dominates ground friction: friction acts on the free part only
            add_contact_impulses(
                kp,
                kv,
                (one - s) * mu,
                size,
                static_pos_in,
                static_rot_in,
                static_size_in,
                x_o,
                rot_o,
                s * v_carry + v_e,
                s * w_h + w_e,
                lane,
                lanes,
                b,
                n,
                impulse_v_out,
                impulse_w_out,
            )
            _block_barrier()  # every lane's impulses are summed
            if lane == 0:
                free = one - s
                v_new = v_e + dt * (impulse_v_out[b, n] - s * grasp_decay * v_e + free * (fall - free_damping * v_e))
                w_new = w_e + dt * (impulse_w_out[b, n] - s * grasp_decay * w_e - free * free_damping * w_e)

                turn_h = exp_so3(dt * w_h)
                x_h_new = x_h + dt * v_h
                x_o_new = x_o + s * (x_h_new + turn_h * r - x_o) + dt * v_new
                rot_o_new = orthonormalize(exp_so3(dt * w_new) * exp_so3(s * dt * w_h) * rot_o)
                g_new = grasp_out[b, n] + dt * hand_vel_in[b, n, 6]
                d_new = tip_distance(x_h_new, x_o_new, rot_o_new, size)

                hand_pos_out[b, n + 1] = x_h_new
                hand_rot_out[b, n + 1] = turn_h * hand_rot_out[b, n]
                grasp_out[b, n + 1] = g_new
                grasped_out[b, n + 1] = _grasp_switch(d_new, g_new, s, grasp_tau)
                tip_distance_out[b, n + 1] = d_new
                object_pos_out[b, n + 1] = x_o_new
                object_rot_out[b, n + 1] = rot_o_new
                object_own_vel_out[b, n + 1] = v_new
                object_own_ang_vel_out[b, n + 1] = w_new
                object_vel_out[b, n + 1] = s * v_carry + v_new
                object_ang_vel_out[b, n + 1] = s * w_h + w_new

    @wp.kernel(module="unique", module_options={"optimization_level": OPTIMIZATION_LEVEL})
    def _gather_frames(
        # Model:
        steps_per_frame: int,
        # Data in (per step):
        hand_pos_in: wp.array2d(dtype=vec3),
        hand_rot_in: wp.array2d(dtype=mat33),
        grasp_in: wp.array2d(dtype=dtype),
        grasped_in: wp.array2d(dtype=dtype),
        tip_distance_in: wp.array2d(dtype=dtype),
        object_pos_in: wp.array2d(dtype=vec3),
        object_rot_in: wp.array2d(dtype=mat33),
        object_vel_in: wp.array2d(dtype=vec3),
        object_ang_vel_in: wp.array2d(dtype=vec3),
        # Data out (per frame):
        hand_pos_out: wp.array2d(dtype=vec3),
        hand_rot_out: wp.array2d(dtype=mat33),
        grasp_out: wp.array2d(dtype=dtype),
        grasped_out: wp.array2d(dtype=dtype),
        tip_distance_out: wp.array2d(dtype=dtype),
        object_pos_out: wp.array2d(dtype=vec3),
        object_rot_out: wp.array2d(dtype=mat33),
        object_vel_out: wp.array2d(dtype=vec3),
        object_ang_vel_out: wp.array2d(dtype=vec3),
    ):
        b, f = wp.tid()
        n = f * steps_per_frame
        hand_pos_out[b, f] = hand_pos_in[b, n]
        hand_rot_out[b, f] = hand_rot_in[b, n]
        grasp_out[b, f] = grasp_in[b, n]
        grasped_out[b, f] = grasped_in[b, n]
        tip_distance_out[b, f] = tip_distance_in[b, n]
        object_pos_out[b, f] = object_pos_in[b, n]
        object_rot_out[b, f] = object_rot_in[b, n]
        object_vel_out[b, f] = object_vel_in[b, n]
        object_ang_vel_out[b, f] = object_ang_vel_in[b, n]

    return _rollout, _gather_frames


@dataclasses.dataclass
class Trajectory:
    """Warp arrays (B, T) of B scenes over T states (steps or frames).

    ``hand_pos``, ``object_pos``, ``object_vel`` [m/s], ``object_ang_vel`` [rad/s]: vec3;
    ``hand_rot``, ``object_rot``: mat33; ``grasp``, ``grasped`` (switch s), ``tip_distance``
    [m]: scalars. The velocities are the object's total ones.
    """

    hand_pos: wp.array
    hand_rot: wp.array
    grasp: wp.array
    grasped: wp.array
    tip_distance: wp.array
    object_pos: wp.array
    object_rot: wp.array
    object_vel: wp.array
    object_ang_vel: wp.array

    @classmethod
    def zeros(cls, num_scenes: int, length: int, dtype, device, requires_grad: bool) -> "Trajectory":
        """Zeroed arrays (num_scenes, length) of scalar type ``dtype`` on ``device``."""
        vec3, mat33 = wp.types.vector(3, dtype), wp.types.matrix((3, 3), dtype)
        types = {"hand_rot": mat33, "object_rot": mat33, "grasp": dtype, "grasped": dtype, "tip_distance": dtype}

        def zeros(name: str) -> wp.array:
            dtype_ = types.get(name, vec3)
            return wp.zeros((num_scenes, length), dtype=dtype_, device=device, requires_grad=requires_grad)

        return cls(*(zeros(field.name) for field in dataclasses.fields(cls)))

    def arrays(self) -> list:
        """The arrays in field order."""
        return [getattr(self, field.name) for field in dataclasses.fields(self)]


@dataclasses.dataclass
class Scratch:
    """Warp arrays (B, T) of vec3 the rollout works in: the object's own velocities ``own_vel``
    [m/s], ``own_ang_vel`` [rad/s] per state (T = S + 1), and the contact impulse sums
    ``impulse_v`` [m/s^2], ``impulse_w`` [rad/s^2] per step (T = S), accumulated into: zero them
    before each rollout (:meth:`clear`)."""

    own_vel: wp.array
    own_ang_vel: wp.array
    impulse_v: wp.array
    impulse_w: wp.array

    @classmethod
    def zeros(cls, num_scenes: int, num_steps: int, dtype, device, requires_grad: bool) -> "Scratch":
        """Zeroed scratch for ``num_scenes`` scenes of ``num_steps`` steps of scalar type ``dtype``."""
        vec3 = wp.types.vector(3, dtype)

        def zeros(length: int) -> wp.array:
            return wp.zeros((num_scenes, length), dtype=vec3, device=device, requires_grad=requires_grad)

        return cls(zeros(num_steps + 1), zeros(num_steps + 1), zeros(num_steps), zeros(num_steps))

    def clear(self) -> None:
        """Zero the impulse sums (the velocities are written whole by every rollout)."""
        self.impulse_v.zero_()
        self.impulse_w.zero_()


def lanes(device: wp.Device) -> int:
    """Threads per scene of :func:`rollout` on ``device``: :data:`CUDA_LANES` on a GPU, on the CPU
    one (Warp runs a CPU block as one thread; with ``wp.config.enable_cpu_blocks`` as many fibers)."""
    return 1 if device.is_cpu and not wp.config.enable_cpu_blocks else CUDA_LANES


def rollout(
    config,
    dt: float,
    object_size: wp.array,
    static_pos: wp.array,
    static_rot: wp.array,
    static_size: wp.array,
    hand_pos0: wp.array,
    hand_rot0: wp.array,
    grasp0: wp.array,
    hand_vel: wp.array,
    object_pos0: wp.array,
    object_rot0: wp.array,
    steps: Trajectory,
    scratch: Scratch,
):
    """Integrate B scenes over S = ``hand_vel.shape[1]`` steps of ``dt`` [s] into ``steps`` (B, S+1),
    working in the cleared ``scratch`` (B, S + 1), with :func:`lanes` threads per scene.

    ``config`` holds the physics constants (``warpskill.engine.simulation.PhysicsConfig``); arrays are
    (B,) (statics (B, K), ``hand_vel`` (B, S, 7) = v_h, w_h, grasp rate).
    """
    lanes_per_scene = lanes(hand_vel.device)
    wp.launch(
        _kernels(hand_vel.dtype)[0],
        dim=(hand_vel.shape[0], lanes_per_scene),
        block_dim=lanes_per_scene,
        inputs=[
            dt,
            config.kp,
            config.kv,
            config.mu,
            config.gravity,
            config.free_damping,
            config.grasp_decay,
            config.grasp_tau,
            object_size,
            static_pos,
            static_rot,
            static_size,
            hand_pos0,
            hand_rot0,
            grasp0,
            hand_vel,
            object_pos0,
            object_rot0,
        ],
        outputs=[
            steps.hand_pos,
            steps.hand_rot,
            steps.grasp,
            steps.grasped,
            steps.tip_distance,
            steps.object_pos,
            steps.object_rot,
            scratch.own_vel,
            scratch.own_ang_vel,
            steps.object_vel,
            steps.object_ang_vel,
            scratch.impulse_v,
            scratch.impulse_w,
        ],
        device=hand_vel.device,
    )


def gather_frames(steps_per_frame: int, steps: Trajectory, frames: Trajectory):
    """Copy every ``steps_per_frame``-th state of ``steps`` (B, S + 1) into ``frames`` (B, N)."""
    wp.launch(
        _kernels(steps.grasp.dtype)[1],
        dim=frames.grasp.shape,
        inputs=[steps_per_frame, *steps.arrays()],
        outputs=frames.arrays(),
        device=steps.grasp.device,
    )
