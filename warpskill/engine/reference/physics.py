"""The rollout of ``warpskill.engine.simulation.simulate`` in plain PyTorch, differentiated by autograd.

The same model (docs/architecture.md, "Physics"): 62 contact sample points per object,
SDF point impulses against the ground and the static cuboids, the sigmoid grasp switch with
its grasp and release events, and the semi-implicit step. Scenes and sample points are
batched in tensors; steps run one after another in Python, as a Torch implementation
of a time-stepper must. Slow and memory hungry (autograd keeps every step), but short and
independent of the Warp kernels: the oracle they are tested against, and the "original
approach" baseline of ``warpskill bench speed``.
"""

from __future__ import annotations

import torch

from warpskill.engine.records import Rollout, SceneInputs
from warpskill.engine.reference.geometry import (
    box_distance,
    exp_rotation,
    orthonormalize,
    resting_box_distance,
)
from warpskill.engine.simulation import PhysicsConfig


def sample_points(size: torch.Tensor) -> torch.Tensor:
    """The 62 contact sample points (B, 62, 3) [m] of cuboids of edge lengths ``size`` (B, 3),
    in the cuboid frame: 5 x 5 grids on the bottom and top faces, and the 3 interior points
    of each vertical edge."""
    grid = torch.linspace(-0.5, 0.5, 5, dtype=size.dtype, device=size.device)
    x, y = torch.meshgrid(grid, grid, indexing="xy")
    face = torch.stack([x.flatten(), y.flatten()], -1)  # (25, 2)
    half = torch.full_like(face[:, :1], 0.5)
    corners = torch.tensor([[-0.5, -0.5], [0.5, -0.5], [-0.5, 0.5], [0.5, 0.5]], dtype=size.dtype, device=size.device)
    edge = torch.cat([corners.repeat_interleave(3, 0), grid[1:4].repeat(4)[:, None]], -1)  # (12, 3)
    unit = torch.cat([torch.cat([face, -half], -1), torch.cat([face, half], -1), edge])
    return unit * size[:, None, :]


def grasp_switch(tip_distance: torch.Tensor, grasp: torch.Tensor, held: torch.Tensor, tau: float) -> torch.Tensor:
    """s = min(sigmoid(grasp / tau), max(held, sigmoid(-tip_distance / tau))) in [0, 1] (1 = grasped),
    ``held`` the previous state (0 at the start): once the tip is in, the grasp holds until
    the signal lets go."""
    return torch.minimum(torch.sigmoid(grasp / tau), torch.maximum(held, torch.sigmoid(-tip_distance / tau)))


def tip_distance(hand_pos, object_pos, object_rot, object_size) -> torch.Tensor:
    """Signed distance (B,) [m] of hand tips (B, 3) from their cuboids (negative inside)."""
    local = ((hand_pos - object_pos).unsqueeze(-2) @ object_rot).squeeze(-2)  # R^T (x_h - x_o)
    return box_distance(local, 0.5 * object_size)[0]


def contact_impulses(
    config: PhysicsConfig,
    friction: torch.Tensor,
    points: torch.Tensor,
    statics: tuple[torch.Tensor, torch.Tensor, torch.Tensor],
    object_pos: torch.Tensor,
    object_rot: torch.Tensor,
    velocity: torch.Tensor,
    angular_velocity: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Contact impulses (j_v [m/s^2], j_w [rad/s^2]), each (B, 3), on B cuboids.

    Args:
        config: kp and kv.
        friction: (B,) tangential damping mu [1/s] of each scene.
        points: (B, P, 3) sample points in the cuboid frame [m].
        statics: static cuboid centres (B, K, 3), rotations (B, K, 3, 3), sizes (B, K, 3).
        object_pos, object_rot: (B, 3), (B, 3, 3) cuboid pose.
        velocity, angular_velocity: (B, 3) total velocities [m/s], [rad/s].
    """
    offset = points @ object_rot.transpose(-1, -2)  # (B, P, 3) world offsets q
    point_vel = velocity[:, None] + torch.linalg.cross(angular_velocity[:, None].expand_as(offset), offset)
    world = object_pos[:, None] + offset  # (B, P, 3)
    static_pos, static_rot, static_size = statics
    local = (world[:, None] - static_pos[:, :, None]) @ static_rot  # (B, K, P, 3) in the static frames
    d_static, n_local = resting_box_distance(local, 0.5 * static_size[:, :, None])
    n_static = n_local @ static_rot.transpose(-1, -2)
    d = torch.cat([world[:, None, :, 2], d_static], 1)  # (B, 1 + K, P): the ground first
    up = torch.zeros_like(world[:, None])
    up[..., 2] = 1.0
    normal = torch.cat([up, n_static], 1)
    v = point_vel[:, None]
    vn = (v * normal).sum(-1, keepdim=True)
    push = (-config.kp * d.unsqueeze(-1) - config.kv * vn.clamp_max(0.0)).clamp_min(0.0)
    slip = torch.where(push > 0, friction[:, None, None, None] * (v - vn * normal), torch.zeros_like(v))
    impulse = push * normal - slip  # (B, 1 + K, P, 3)
    torque = torch.linalg.cross(offset[:, None].expand_as(impulse), impulse)
    return impulse.sum((1, 2)), torque.sum((1, 2))


def simulate_reference(
    inputs: SceneInputs,
    *,
    steps_per_frame: int,
    fps: float,
    config: PhysicsConfig = PhysicsConfig(),
) -> Rollout:
    """Roll out B scenes exactly as :func:`warpskill.engine.simulation.simulate` (same arguments,
    the same :meth:`~warpskill.engine.records.SceneInputs.check` and
    :class:`~warpskill.engine.records.Rollout`), in Torch operations.

    Args:
        inputs: the B scenes; ``hand_vel`` (B, S, 7) with S = (N - 1) * steps_per_frame.
        steps_per_frame: integration steps per frame.
        fps: frame rate [1/s].
        config: physics constants.

    Returns:
        The rollout at the N frames, differentiable by autograd.
    """
    SceneInputs.check(inputs, steps_per_frame=steps_per_frame, fps=fps)
    hand_pos0, hand_rot0, grasp0, hand_vel = inputs.hand_pos0, inputs.hand_rot0, inputs.grasp0, inputs.hand_vel
    object_pos0, object_rot0, object_size = inputs.object_pos0, inputs.object_rot0, inputs.object_size
    static_pos, static_rot, static_size = inputs.static_pos, inputs.static_rot, inputs.static_size
    dt = 1.0 / (fps * steps_per_frame)
    points = sample_points(object_size)
    statics = (static_pos, static_rot, static_size)
    fall = torch.zeros_like(object_pos0)
    fall[:, 2] = -config.gravity

    def carry(state: dict[str, torch.Tensor], v_h: torch.Tensor, w_h: torch.Tensor) -> torch.Tensor:
        """Velocity [m/s] of the object's centre rigidly carried by the hand."""
        return v_h + torch.linalg.cross(w_h, state["object_pos"] - state["hand_pos"])

    def frame(state: dict[str, torch.Tensor], total_vel: torch.Tensor, total_ang_vel: torch.Tensor) -> dict:
        return {**{k: state[k] for k in _FRAME_STATE}, "object_vel": total_vel, "object_ang_vel": total_ang_vel}

    distance = tip_distance(hand_pos0, object_pos0, object_rot0, object_size)
    state = {
        "hand_pos": hand_pos0,
        "hand_rot": hand_rot0,
        "grasp": grasp0,
        "grasped": grasp_switch(distance, grasp0, torch.zeros_like(grasp0), config.grasp_tau),
        "tip_distance": distance,
        "object_pos": object_pos0,
        "object_rot": object_rot0,
        "own_vel": torch.zeros_like(object_pos0),  # the object starts at rest
        "own_ang_vel": torch.zeros_like(object_pos0),
    }
    previous_switch = state["grasped"]  # s_{-1} = s_0: no event at t = 0
    s0 = state["grasped"][:, None]
    frames = [frame(state, s0 * carry(state, hand_vel[:, 0, :3], hand_vel[:, 0, 3:6]), s0 * hand_vel[:, 0, 3:6])]
    for n in range(hand_vel.shape[1]):
        v_h, w_h, grasp_rate = hand_vel[:, n, :3], hand_vel[:, n, 3:6], hand_vel[:, n, 6]
        s = state["grasped"]
        carried = carry(state, v_h, w_h)
        new, total_vel, total_ang_vel = _step(
            config, dt, points, statics, fall, state, s - previous_switch, v_h, w_h, grasp_rate, carried
        )
        new["tip_distance"] = tip_distance(new["hand_pos"], new["object_pos"], new["object_rot"], object_size)
        new["grasped"] = grasp_switch(new["tip_distance"], new["grasp"], s, config.grasp_tau)
        previous_switch, state = s, new
        if (n + 1) % steps_per_frame == 0:
            frames.append(frame(state, total_vel, total_ang_vel))
    return Rollout(**{name: torch.stack([f[name] for f in frames], 1) for name in frames[0]})


_FRAME_STATE = ("hand_pos", "hand_rot", "grasp", "grasped", "tip_distance", "object_pos", "object_rot")


def _step(config, dt, points, statics, fall, state, switch_change, v_h, w_h, grasp_rate, carried):
    """One semi-implicit step n -> n + 1 without the switch of the new state.

    Returns the new state (less ``tip_distance`` and ``grasped``) and the object's total
    velocities (B, 3) over the step.
    """
    s = state["grasped"][:, None]
    grasp_event = switch_change.clamp_min(0.0)[:, None]  # a grasp zeroes the own velocity
    release_event = (-switch_change).clamp_min(0.0)[:, None]  # a release hands the hand's over
    own_vel = state["own_vel"] - grasp_event * state["own_vel"] + release_event * carried
    own_ang_vel = state["own_ang_vel"] - grasp_event * state["own_ang_vel"] + release_event * w_h
    free = 1.0 - s
    j_v, j_w = contact_impulses(
        config,
        free[:, 0] * config.mu,  # a firm grip dominates ground friction
        points,
        statics,
        state["object_pos"],
        state["object_rot"],
        s * carried + own_vel,
        s * w_h + own_ang_vel,
    )
    decay, damping = config.grasp_decay, config.free_damping
    own_vel = own_vel + dt * (j_v - s * decay * own_vel + free * (fall - damping * own_vel))
    own_ang_vel = own_ang_vel + dt * (j_w - s * decay * own_ang_vel - free * damping * own_ang_vel)
    turn = exp_rotation(dt * w_h)
    hand_pos = state["hand_pos"] + dt * v_h
    offset = state["object_pos"] - state["hand_pos"]
    carried_pos = hand_pos + (turn @ offset[:, :, None])[..., 0]
    object_pos = state["object_pos"] + s * (carried_pos - state["object_pos"]) + dt * own_vel
    object_rot = exp_rotation(dt * own_ang_vel) @ exp_rotation(s * dt * w_h) @ state["object_rot"]
    new = {
        "hand_pos": hand_pos,
        "hand_rot": turn @ state["hand_rot"],
        "grasp": state["grasp"] + dt * grasp_rate,
        "object_pos": object_pos,
        "object_rot": orthonormalize(object_rot),
        "own_vel": own_vel,
        "own_ang_vel": own_ang_vel,
    }
    return new, s * carried + own_vel, s * w_h + own_ang_vel

