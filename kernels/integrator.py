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

import functools
from typing import Any

import warp as wp

from . import OPTIMIZATION_LEVEL
from .contact import contact_impulses_func, tip_distance
from .geometry import exp_so3, orthonormalize
from .records import records, zeros

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
    Physics, Scene, Trajectory, Scratch = records(dtype)
    add_contact_impulses = contact_impulses_func(dtype)

    @wp.kernel(module="unique", module_options={"optimization_level": OPTIMIZATION_LEVEL})
    def _rollout(
        # Model:
        physics: Physics,
        # Data in:
        scene: Scene,
        # Data out (per step, S + 1 states; impulses S steps):
        steps: Trajectory,
        scratch: Scratch,
    ):
        b, lane = wp.tid()
        lanes = wp.block_dim()
        zero = dtype(0.0)
        one = dtype(1.0)
        dt = physics.dt
        size = scene.object_size[b]
        fall = vec3(zero, zero, -physics.gravity)

        if lane == 0:  # state 0: the object at rest (own velocities zero)
            d0 = tip_distance(scene.hand_pos0[b], scene.object_pos0[b], scene.object_rot0[b], size)
            s0 = _grasp_switch(d0, scene.grasp0[b], zero, physics.grasp_tau)
            v_h0 = vec3(scene.hand_vel[b, 0, 0], scene.hand_vel[b, 0, 1], scene.hand_vel[b, 0, 2])
            w_h0 = vec3(scene.hand_vel[b, 0, 3], scene.hand_vel[b, 0, 4], scene.hand_vel[b, 0, 5])
            steps.hand_pos[b, 0] = scene.hand_pos0[b]
            steps.hand_rot[b, 0] = scene.hand_rot0[b]
            steps.grasp[b, 0] = scene.grasp0[b]
            steps.grasped[b, 0] = s0
            steps.tip_distance[b, 0] = d0
            steps.object_pos[b, 0] = scene.object_pos0[b]
            steps.object_rot[b, 0] = scene.object_rot0[b]
            scratch.own_vel[b, 0] = vec3(zero, zero, zero)
            scratch.own_ang_vel[b, 0] = vec3(zero, zero, zero)
            steps.object_vel[b, 0] = s0 * (v_h0 + wp.cross(w_h0, scene.object_pos0[b] - scene.hand_pos0[b]))
            steps.object_ang_vel[b, 0] = s0 * w_h0

        for n in range(scene.hand_vel.shape[1]):
            _block_barrier()  # state n, written by lane 0, is seen by every lane
            x_h = steps.hand_pos[b, n]
            x_o = steps.object_pos[b, n]
            rot_o = steps.object_rot[b, n]
            s = steps.grasped[b, n]
            ds = s - steps.grasped[b, wp.max(n - 1, 0)]
            v_h = vec3(scene.hand_vel[b, n, 0], scene.hand_vel[b, n, 1], scene.hand_vel[b, n, 2])
            w_h = vec3(scene.hand_vel[b, n, 3], scene.hand_vel[b, n, 4], scene.hand_vel[b, n, 5])
            r = x_o - x_h
            v_carry = v_h + wp.cross(w_h, r)

            # grasp event zeroes the own velocity, release hands over the hand's
            grasp_event = wp.max(ds, zero)
            release_event = wp.max(-ds, zero)
            v_o = scratch.own_vel[b, n]
            w_o = scratch.own_ang_vel[b, n]
            v_e = v_o - grasp_event * v_o + release_event * v_carry
            w_e = w_o - grasp_event * w_o + release_event * w_h

            # a firm grip dominates ground friction: friction acts on the free part only
            add_contact_impulses(physics, (one - s) * physics.mu, scene, size, x_o, rot_o, s * v_carry + v_e,
                                 s * w_h + w_e, lane, lanes, b, n, scratch)
            _block_barrier()  # every lane's impulses are summed
            if lane == 0:
                free = one - s
                decay, damping = physics.grasp_decay, physics.free_damping
                v_new = v_e + dt * (scratch.impulse_v[b, n] - s * decay * v_e + free * (fall - damping * v_e))
                w_new = w_e + dt * (scratch.impulse_w[b, n] - s * decay * w_e - free * damping * w_e)

                turn_h = exp_so3(dt * w_h)
                x_h_new = x_h + dt * v_h
                x_o_new = x_o + s * (x_h_new + turn_h * r - x_o) + dt * v_new
                rot_o_new = orthonormalize(exp_so3(dt * w_new) * exp_so3(s * dt * w_h) * rot_o)
                g_new = steps.grasp[b, n] + dt * scene.hand_vel[b, n, 6]
                d_new = tip_distance(x_h_new, x_o_new, rot_o_new, size)

                steps.hand_pos[b, n + 1] = x_h_new
                steps.hand_rot[b, n + 1] = turn_h * steps.hand_rot[b, n]
                steps.grasp[b, n + 1] = g_new
                steps.grasped[b, n + 1] = _grasp_switch(d_new, g_new, s, physics.grasp_tau)
                steps.tip_distance[b, n + 1] = d_new
                steps.object_pos[b, n + 1] = x_o_new
                steps.object_rot[b, n + 1] = rot_o_new
                scratch.own_vel[b, n + 1] = v_new
                scratch.own_ang_vel[b, n + 1] = w_new
                steps.object_vel[b, n + 1] = s * v_carry + v_new
                steps.object_ang_vel[b, n + 1] = s * w_h + w_new

    @wp.kernel(module="unique", module_options={"optimization_level": OPTIMIZATION_LEVEL})
    def _gather_frames(
        # Model:
        steps_per_frame: int,
        # Data in (per step):
        steps: Trajectory,
        # Data out (per frame):
        frames: Trajectory,
    ):
        b, f = wp.tid()
        n = f * steps_per_frame
        frames.hand_pos[b, f] = steps.hand_pos[b, n]
        frames.hand_rot[b, f] = steps.hand_rot[b, n]
        frames.grasp[b, f] = steps.grasp[b, n]
        frames.grasped[b, f] = steps.grasped[b, n]
        frames.tip_distance[b, f] = steps.tip_distance[b, n]
        frames.object_pos[b, f] = steps.object_pos[b, n]
        frames.object_rot[b, f] = steps.object_rot[b, n]
        frames.object_vel[b, f] = steps.object_vel[b, n]
        frames.object_ang_vel[b, f] = steps.object_ang_vel[b, n]

    return _rollout, _gather_frames


def trajectory(num_scenes: int, length: int, dtype, device, requires_grad: bool):
    """A zeroed ``Trajectory`` record (:mod:`.records`) of ``num_scenes`` scenes over ``length`` states."""
    kind = records(dtype).Trajectory
    return zeros(kind, dict.fromkeys(kind.vars, (num_scenes, length)), device, requires_grad)


def scratch(num_scenes: int, num_steps: int, dtype, device, requires_grad: bool):
    """A zeroed ``Scratch`` record (:mod:`.records`) for ``num_scenes`` scenes of ``num_steps`` steps; its impulse
    sums are accumulated into: zero them before each rollout."""
    states, steps = (num_scenes, num_steps + 1), (num_scenes, num_steps)
    shapes = {"own_vel": states, "own_ang_vel": states, "impulse_v": steps, "impulse_w": steps}
    return zeros(records(dtype).Scratch, shapes, device, requires_grad)


def lanes(device: wp.Device) -> int:
    """Threads per scene of :func:`rollout` on ``device``: :data:`CUDA_LANES` on a GPU, on the CPU
    one (Warp runs a CPU block as one thread; with ``wp.config.enable_cpu_blocks`` as many fibers)."""
    return 1 if device.is_cpu and not wp.config.enable_cpu_blocks else CUDA_LANES


def rollout(physics, scene, steps, scratch) -> None:
    """Integrate the B scenes of ``scene`` over S = ``hand_vel.shape[1]`` steps of ``physics.dt`` [s] into
    ``steps`` (B, S + 1), working in ``scratch`` (its impulse sums zeroed), with :func:`lanes` threads per scene
    (records of :mod:`.records`)."""
    device = scene.hand_vel.device
    lanes_per_scene = lanes(device)
    wp.launch(_kernels(scene.hand_vel.dtype)[0], dim=(scene.hand_vel.shape[0], lanes_per_scene),
              block_dim=lanes_per_scene, inputs=[physics, scene], outputs=[steps, scratch], device=device)


def gather_frames(steps_per_frame: int, steps, frames) -> None:
    """Copy every ``steps_per_frame``-th state of the trajectory ``steps`` (B, S + 1) into ``frames`` (B, N)."""
    wp.launch(_kernels(steps.grasp.dtype)[1], dim=frames.grasp.shape, inputs=[steps_per_frame, steps],
              outputs=[frames], device=steps.grasp.device)
