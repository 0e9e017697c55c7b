"""Replaying Panda plans in Newton: a dynamic, position-controlled robot that agrees with MuJoCo (CPU)."""

from __future__ import annotations

import numpy as np
import pytest
from robot_support import require_robot

robot = require_robot("placo", "mujoco", "newton", "trimesh")  # trimesh: Newton's URDF importer reads meshes with it
from warpskill.contract.reconstruction import Reconstruction  # noqa: E402
from warpskill.synthetic import make_demonstration  # noqa: E402

# Every test here plans and replays in MuJoCo and Newton (seconds each).
pytestmark = pytest.mark.slow


def _replays(action: str, seed: int):
    recon = Reconstruction(**make_demonstration(action, seed=seed, noise="none").truth)
    plan = robot.retarget(recon)
    mujoco = robot.replay(plan, recon, engine="mujoco")
    newton = robot.replay(plan, recon, engine="newton", device="cpu")
    assert newton.engine == "newton"
    assert newton.success == mujoco.success, (mujoco.evaluation.checks, newton.evaluation.checks)
    assert newton.reconstruction.num_frames == mujoco.reconstruction.num_frames
    assert np.isfinite(newton.reconstruction.object_pos).all()
    return plan, recon, mujoco, newton


def _planned_joints(plan, recon) -> np.ndarray:
    times = np.arange(plan.start_time, plan.t[-1] + 1e-9, 1.0 / float(recon.fps))
    return np.stack([np.interp(times, plan.t, plan.q[:, i]) for i in range(7)], axis=1)


def test_newton_agrees_with_mujoco_on_a_pick_up():
    plan, recon, mujoco, newton = _replays("pick_up", 0)
    assert newton.success
    replayed = newton.reconstruction
    # Both engines carry the cuboid along the same path (the robot tracks the same plan).
    assert np.abs(replayed.object_pos - mujoco.reconstruction.object_pos).max() < 0.03
    # The force-limited fingers close on the cuboid and hold it, for about as long as in MuJoCo.
    held, held_mujoco = replayed.grasped > 0.5, mujoco.reconstruction.grasped > 0.5
    assert abs(int(held.sum()) - int(held_mujoco.sum())) <= 0.2 * held_mujoco.sum()
    # The arm is simulated under position control: its joints lag the plan as MuJoCo's
    # drives do, they are not posed on it.
    error = np.abs(newton.joints - _planned_joints(plan, recon)).max()
    assert 0.01 < error < 0.2
    assert np.abs(newton.joints - mujoco.joints).max() < 0.01


def test_newton_agrees_with_mujoco_on_a_push():
    plan, recon, mujoco, newton = _replays("push_left_to_right", 2)
    assert plan.grasp_kind == "push"
    assert newton.success
    assert np.abs(newton.reconstruction.object_pos - mujoco.reconstruction.object_pos).max() < 0.03
    assert 0.01 < np.abs(newton.joints - _planned_joints(plan, recon)).max() < 0.2


def test_graph_replay_is_the_replay_of_per_kernel_launches():
    # Each step replays a captured Warp graph (a CPU graph here): the same kernels on the same
    # arrays as launching them one by one, so the sampled states are bit for bit the same.
    from warpskill.robot import replay_newton

    recon = Reconstruction(**make_demonstration("push_left_to_right", seed=2, noise="none").truth)
    plan = robot.retarget(recon)
    scene = plan.scene(recon)
    times = np.arange(plan.start_time, plan.t[-1] + 1e-9, 1.0 / float(scene.fps))[:12]
    graph = replay_newton.simulate(plan, scene, times, device="cpu", capture=True)
    launches = replay_newton.simulate(plan, scene, times, device="cpu", capture=False)
    assert set(graph) == set(launches)
    for key in graph:
        assert graph[key].shape[0] == len(times)
        np.testing.assert_array_equal(graph[key], launches[key], err_msg=key)
