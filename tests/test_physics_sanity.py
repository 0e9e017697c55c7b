"""Physical behaviour of float32 rollouts at the default step (12 fps, 20 substeps)."""

import numpy as np
import pytest
import torch

from warpskill.engine.records import SceneInputs
from warpskill.engine.reference.physics import simulate_reference
from warpskill.engine.simulation import PhysicsConfig, simulate, substeps_per_frame

FPS = 12.0
SPF = substeps_per_frame(FPS)
REST_DEPTH = PhysicsConfig().gravity / (25 * PhysicsConfig().kp)  # a face's 25 points carry the weight [m]


def _yaw(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _tilt(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _run(duration: float, **scene) -> object:
    """Simulate the float32 scenes of :func:`_inputs`."""
    return simulate(_inputs(duration, **scene), steps_per_frame=SPF, fps=FPS)


def _inputs(duration: float, *, hand_vel=None, hand_pos0=None, grasp0=None, statics=(), dtype=torch.float32,
            **objects) -> SceneInputs:
    """The inputs of B scenes in ``dtype``; objects: object_pos0, object_rot0, object_size as (B, ...)
    arrays; statics: one (pos, yaw, size) per scene (same K = 0 or 1 for all)."""
    B = len(objects["object_pos0"])
    steps = int(round(duration * FPS)) * SPF
    f32 = lambda a: torch.tensor(np.asarray(a, dtype=np.float64), dtype=dtype)  # noqa: E731
    K = 1 if statics else 0
    inputs = SceneInputs(
        hand_pos0=f32(np.tile([0.0, 0.0, 1.0], (B, 1)) if hand_pos0 is None else hand_pos0),
        hand_rot0=f32(np.tile(np.eye(3), (B, 1, 1))),
        grasp0=f32(np.full(B, -1.0) if grasp0 is None else grasp0),
        hand_vel=f32(np.zeros((B, steps, 7)) if hand_vel is None else hand_vel),
        object_pos0=f32(objects["object_pos0"]),
        object_rot0=f32(objects["object_rot0"]),
        object_size=f32(objects["object_size"]),
        static_pos=f32([[s[0]] for s in statics]).reshape(B, K, 3),
        static_rot=f32([[_yaw(s[1])] for s in statics]).reshape(B, K, 3, 3),
        static_size=f32([[s[2]] for s in statics]).reshape(B, K, 3),
    )
    return inputs


def _corners(pos: torch.Tensor, rot: torch.Tensor, size: np.ndarray) -> np.ndarray:
    """(..., 8, 3) corners of cuboids at poses (..., 3), (..., 3, 3)."""
    signs = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    local = signs * size[:, None, None, :]  # (B, 1, 8, 3)
    return pos.numpy()[..., None, :] + np.einsum("bnij,bnkj->bnki", rot.numpy(), local)


def test_resting_cuboids_stay_put_for_five_seconds():
    size = np.array([[0.1, 0.08, 0.06], [0.07, 0.05, 0.04]])
    # on the ground; on top of a static cuboid
    pos = np.array([[0.3, 0.1, 0.03], [0.0, 0.0, 0.08 + 0.02]])
    statics = [((0.0, 0.0, 0.04), 0.0, (0.2, 0.2, 0.08))] * 2
    rot = np.stack([_yaw(0.4), _yaw(-0.3)])
    out = _run(5.0, object_pos0=pos, object_rot0=rot, object_size=size, statics=statics)
    drift = (out.object_pos - out.object_pos[:, :1]).norm(dim=-1)
    assert drift.max() < 1e-3  # [m], the settling depth included
    assert out.object_pos[:, -1, 2].numpy() == pytest.approx(pos[:, 2] - REST_DEPTH, abs=1e-4)
    assert (out.object_rot - out.object_rot[:, :1]).abs().max() < 1e-3
    assert out.object_vel[:, -1].norm(dim=-1).max() < 1e-4  # [m/s]


def test_dropped_cuboids_settle_on_the_ground_and_on_a_static_cuboid():
    """Dropped from 15 cm onto the ground (the static cuboid far away) and onto the static's
    top: level cuboids come to rest; tilted ones land on an edge and, with unit rotational
    inertia, rock for seconds, but never sink far or pass through."""
    size = np.array([[0.08, 0.06, 0.05]] * 4)
    rot = np.stack([_yaw(0.3), _yaw(-0.6), _yaw(0.3) @ _tilt(0.3), _yaw(-0.6) @ _tilt(-0.3)])
    pos = np.array([[0.6, 0.0, 0.15], [0.0, 0.0, 0.25]] * 2)
    support = np.array([0.0, 0.1] * 2)  # height of the supporting surface [m]
    statics = [((0.0, 0.0, 0.05), 0.2, (0.3, 0.3, 0.1))] * 4
    out = _run(3.0, object_pos0=pos, object_rot0=rot, object_size=size, statics=statics)
    lowest = _corners(out.object_pos, out.object_rot, size)[..., 2].min(axis=-1) - support[:, None]  # (B, N)
    rest = slice(24, None)  # after 2 s
    assert out.object_vel[:2, rest].norm(dim=-1).max() < 1e-4
    assert out.object_ang_vel[:2, rest].norm(dim=-1).max() < 1e-4
    assert np.abs(lowest[:2, rest] + REST_DEPTH).max() < 1e-4  # level, 0.8 mm deep: within 1 mm
    assert lowest.min() > -0.01  # the deepest corner at impact [m]
    assert out.object_pos[1::2, :, 2].min() > 0.1  # centres never below the static's top


def test_grasped_cuboid_follows_the_hand():
    duration = 2.0
    steps = int(round(duration * FPS)) * SPF
    t = np.arange(steps) / (FPS * SPF)
    vel = np.zeros((1, steps, 7))
    vel[0, t < 0.5, 2] = 0.4  # lift 20 cm
    vel[0, t >= 0.5, :6] = [0.2, 0.1, 0.05, 0.6, -0.4, 1.2]  # move and turn
    size = np.array([[0.08, 0.06, 0.05]])
    # the tip 1 cm off the centre inside the cuboid, the grasp closed
    out = _run(duration, hand_vel=vel, hand_pos0=[[0.01, 0.0, 0.025]], grasp0=[0.05],
               object_pos0=[[0.0, 0.0, 0.025]], object_rot0=_yaw(0.2)[None], object_size=size)  # fmt: skip
    assert out.grasped.min() > 0.999
    R_h, R_o = out.hand_rot[0], out.object_rot[0]
    offset = torch.einsum("nji,nj->ni", R_h, out.object_pos[0] - out.hand_pos[0])  # in the hand frame
    relative = R_h.transpose(-1, -2) @ R_o
    assert (offset - offset[:1]).norm(dim=-1).max() < 1e-5  # [m]
    assert (relative - relative[:1]).abs().max() < 1e-4
    assert out.hand_pos[0, -1, 0] > 0.25 and torch.linalg.det(R_h[-1]) == pytest.approx(1.0, abs=1e-4)


REST = 0.05 - REST_DEPTH  # [m] centre height of the 10 cm tall cuboid of _draw_back_and_lift


def _draw_back_and_lift(dtype=torch.float32) -> SceneInputs:
    """The tip comes 2.5 cm towards a side face from 2 cm off it, then draws back 5 cm the way it
    came while lifting 15 cm (the grasp signal open throughout)."""
    duration = 1.5
    steps = int(round(duration * FPS)) * SPF
    t = np.arange(steps) / (FPS * SPF)
    vel = np.zeros((1, steps, 7))
    vel[0, t < 0.25, 0] = 0.1
    back_and_up = (t >= 0.4) & (t < 0.9)
    vel[0, back_and_up, 0], vel[0, back_and_up, 2] = -0.1, 0.3
    return _inputs(duration, hand_vel=vel, hand_pos0=[[-0.05, 0.0, 0.07]], grasp0=[0.02], dtype=dtype,
                   object_pos0=[[0.0, 0.0, REST]], object_rot0=np.eye(3)[None],
                   object_size=np.array([[0.06, 0.06, 0.1]]))


def test_a_grasp_closed_by_a_tip_just_inside_holds_as_the_hand_draws_back_and_lifts():
    """As the tip enters, the closing grasp drags the object along, so the tip gets no deeper
    than a few tau and the switch stays below 1. Drawing back leaves the object behind by
    (1 - s) of the hand's motion and pulls the tip back out: the latched switch keeps the
    grip (an unlatched one lets go within three frames and drops the object)."""
    out = simulate(_draw_back_and_lift(), steps_per_frame=SPF, fps=FPS)
    closed = int(np.argmax(out.grasped[0].numpy() > 0.5))
    assert out.tip_distance[0, closed : closed + 2].min() > -0.003  # [m]
    assert out.grasped[0, closed:].min() > 0.9
    assert out.object_pos[0, -1, 2].item() - REST > 0.12  # carried up (of 15 cm)
    assert out.tip_distance[0, -1] > 0.0  # the tip itself has come out


def test_the_reference_latches_the_grasp_alike():
    """Warp against the plain-Torch reference (float64) where the latch decides: values and
    the gradients of every output's sum."""
    results = []
    for simulator in (simulate, simulate_reference):
        inputs = _draw_back_and_lift(torch.float64).map(lambda v: v.requires_grad_(True))
        out = simulator(inputs, steps_per_frame=SPF, fps=FPS)
        sum(value.sum() for value in vars(out).values()).backward()
        results.append((out, {name: value.grad for name, value in inputs.items()}))
    (warp, warp_grads), (ref, ref_grads) = results
    for name in vars(warp):
        assert (getattr(warp, name) - getattr(ref, name)).abs().max() < 1e-9, name
    for name, grad in warp_grads.items():
        assert (grad - ref_grads[name]).norm() <= 1e-8 * grad.norm(), name


def test_released_cuboid_keeps_the_hand_velocity_and_lands():
    duration = 2.0
    steps = int(round(duration * FPS)) * SPF
    t = np.arange(steps) / (FPS * SPF)
    vel = np.zeros((1, steps, 7))
    vel[0, t < 0.4, 2] = 0.25 / 0.4  # lift 25 cm
    vel[0, (t >= 0.4) & (t < 0.9), 0] = 0.5  # then move along x at 0.5 m/s
    vel[0, t >= 0.8, 6] = -10.0  # and open quickly while moving (g reaches 0 at t = 0.805 s)
    size = np.array([[0.08, 0.06, 0.06]])
    out = _run(duration, hand_vel=vel, hand_pos0=[[0.0, 0.0, 0.03]], grasp0=[0.05], object_size=size,
               object_pos0=[[0.0, 0.0, 0.03 - REST_DEPTH]], object_rot0=np.eye(3)[None])  # fmt: skip
    released = int(np.argmax(out.grasped[0].numpy() < 1e-3))
    assert released == 10  # t = 0.83 s, still moving
    # free flight: the hand's 0.5 m/s, less 0.5 /s air damping over < 0.03 s
    assert out.object_vel[0, released, 0].item() == pytest.approx(0.5 * np.exp(-0.5 * 0.03), rel=0.01)
    flight = out.object_pos[0, released + 1, 0] - out.object_pos[0, released, 0]
    assert flight.item() == pytest.approx(0.5 / FPS, rel=0.05)
    # lands flat on the ground, ahead of where it was let go, and stays
    assert out.object_pos[0, -1, 2].item() == pytest.approx(0.03 - REST_DEPTH, abs=1e-3)
    assert out.object_pos[0, -1, 0] - out.object_pos[0, released, 0] > 0.08
    assert out.object_vel[0, -6:].norm(dim=-1).max() < 1e-2
