"""An object carried into view (held from the first frame): the robot takes it over from rest where it can."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from robot_support import require_robot

robot = require_robot("placo", "mujoco")
from warpskill.contract.reconstruction import Reconstruction  # noqa: E402
from warpskill.robot import retargeting  # noqa: E402
from warpskill.robot.model import make_scene  # noqa: E402
from warpskill.robot.sizes import clear_path, fit_sizes, rest_until  # noqa: E402
from warpskill.synthetic import make_demonstration  # noqa: E402

JOIN = 24  # put_next_to 0 carries the cuboid at this frame; before it, the cuboid comes from far to the left


def truth() -> Reconstruction:
    return Reconstruction(**make_demonstration("put_next_to", seed=0, noise="none").truth)


def carried_in(path_x: np.ndarray) -> Reconstruction:
    """put_next_to 0 held from frame 0: the cuboid (and the hand) at x = ``path_x`` (JOIN,) [m] before JOIN,
    at its height and depth at JOIN, then as demonstrated."""
    recon = truth()
    object_pos, hand_pos, hand_rot = recon.object_pos.copy(), recon.hand_pos.copy(), recon.hand_rot.copy()
    object_pos[:JOIN] = recon.object_pos[JOIN]
    object_pos[:JOIN, 0] = path_x
    hand_pos[:JOIN] = object_pos[:JOIN] + recon.hand_pos[JOIN] - recon.object_pos[JOIN]
    hand_rot[:JOIN] = recon.hand_rot[JOIN]
    grasped = recon.grasped.copy()
    grasped[: np.flatnonzero(recon.grasped > 0.5)[-1] + 1] = 1.0
    return dataclasses.replace(recon, object_pos=object_pos, hand_pos=hand_pos, hand_rot=hand_rot, grasped=grasped)


def steady() -> Reconstruction:
    """Carried in at 0.55 m/s from 1.2 m to the left of where the demonstration carries it."""
    x_join = truth().object_pos[JOIN, 0]
    return carried_in(np.linspace(x_join - 1.2, x_join, JOIN + 1)[:-1])


def onset(recon: Reconstruction) -> int:
    return int(np.flatnonzero(recon.grasped > 0.5)[0])


def reachable(recon: Reconstruction, k: int) -> bool:
    """Whether the robot (standing for the task from the last held frame) can do the task from frame ``k``."""
    fitted, _ = fit_sizes(recon)
    base = make_scene(rest_until(fitted, int(np.flatnonzero(fitted.grasped > 0.5)[-1]))).base
    return retargeting._reachable(rest_until(fitted, k), base)


@pytest.fixture(scope="module")
def carried():
    recon = steady()
    robot_recon, _ = robot.robot_reconstruction(recon)
    return recon, robot_recon, robot.retarget(recon)


@pytest.mark.slow
def test_the_onset_is_the_first_frame_the_robot_can_take_the_object_at(carried):
    recon, robot_recon, _ = carried
    k = onset(robot_recon)
    assert 0 < k < JOIN
    assert reachable(recon, k) and not reachable(recon, k - 1)
    assert np.all(robot_recon.grasped[:k] == 0.0) and np.all(robot_recon.grasped[k:JOIN] == 1.0)


def test_the_object_starts_resting_below_the_onset(carried):
    recon, robot_recon, plan = carried
    k = onset(robot_recon)
    start = robot_recon.object_pos[0]
    np.testing.assert_allclose(robot_recon.object_pos[: k + 1], np.broadcast_to(start, (k + 1, 3)))
    np.testing.assert_allclose(start[:2], recon.object_pos[k, :2])
    corners = robot_recon.object_corners()[: k + 1]
    np.testing.assert_allclose(corners[:, :, 2].min(axis=1), 0.0, atol=1e-9)  # its bottom on the table
    np.testing.assert_allclose(robot_recon.object_rot[0], recon.object_rot[k], atol=1e-9)  # upright, its heading
    # The plan carries that start and grasps at frame k.
    np.testing.assert_allclose(plan.object_pos, robot_recon.object_pos)
    grasp = np.searchsorted(plan.t, plan.grasp_time)
    assert plan.recon_time[grasp] * float(recon.fps) == pytest.approx(k)


def test_the_carried_path_rejoins_the_demonstration(carried):
    recon, robot_recon, _ = carried
    k = onset(robot_recon)
    release = np.flatnonzero(recon.grasped > 0.5)[-1] + 1
    held = slice(k, release + 1)
    pos, bottom = robot_recon.object_pos[held], robot_recon.object_corners()[held, :, 2].min(axis=1)
    np.testing.assert_allclose(pos[:, :2], recon.object_pos[held, :2])
    # Lifted from the table over the static box on the way (the demonstration carries it higher) ...
    top = recon.static_pos[0, 2] + recon.static_size[0, 2] / 2
    over = np.all(np.abs(pos[:, :2] - recon.static_pos[0, :2]) < recon.static_size[0, :2] / 2 + 0.026, axis=1)
    assert over.any() and np.all(bottom[over] >= top - 1e-9) and np.all(bottom >= -1e-9)
    assert np.all(pos[:, 2] <= np.maximum(recon.object_pos[held, 2], top + pos[0, 2]) + 1e-9)
    np.testing.assert_allclose(robot_recon.object_pos[release:], recon.object_pos[release:], atol=1e-3)  # set down
    np.testing.assert_allclose(robot_recon.hand_pos[k:] - robot_recon.object_pos[k:],  # the hand is lowered with it
                               recon.hand_pos[k:] - recon.object_pos[k:], atol=1e-12)


def test_mujoco_replay_starts_the_object_there_and_succeeds(carried):
    recon, robot_recon, plan = carried
    result = robot.replay(plan, recon, engine="mujoco")
    np.testing.assert_allclose(result.reconstruction.object_pos[0], robot_recon.object_pos[0], atol=0.005)
    assert result.success, result.evaluation.checks


def test_newton_starts_the_object_there(carried):
    pytest.importorskip("newton")
    pytest.importorskip("trimesh")
    from warpskill.robot import replay_newton

    recon, robot_recon, plan = carried
    model, info = replay_newton.build_model(plan, recon, device="cpu")
    np.testing.assert_allclose(model.body_q.numpy()[info["object_body"], :3], robot_recon.object_pos[0], atol=1e-6)


def test_an_object_swung_in_is_taken_once_it_has_slowed_down():
    x_join = truth().object_pos[JOIN, 0]
    swing = np.interp(np.arange(JOIN), [0, 10, 14, JOIN], [x_join - 1.2, x_join - 1.2, x_join - 0.2, x_join])
    recon = carried_in(swing)  # 3 m/s from frame 10 to 14, in reach before 14
    assert reachable(recon, 13)
    assert onset(robot.robot_reconstruction(recon)[0]) == 14


def test_an_object_grasped_later_keeps_its_start():
    recon = truth()
    assert onset(recon) > 0
    robot_recon, note = robot.robot_reconstruction(recon)
    fitted, fitted_note = fit_sizes(recon)
    assert note == fitted_note
    for field in dataclasses.fields(Reconstruction):
        np.testing.assert_array_equal(getattr(robot_recon, field.name), getattr(clear_path(fitted), field.name))


@pytest.mark.slow
def test_an_object_first_touched_out_of_reach_is_taken_over_where_the_robot_can():
    x_join = truth().object_pos[JOIN, 0]
    carried = carried_in(np.linspace(x_join - 2.0, x_join, JOIN + 1)[:-1])  # from 2 m away, 1 m/s
    grasped = carried.grasped.copy()
    grasped[:3] = 0.0  # first touched at frame 3, 1.75 m off: the demonstration as it is has no plan
    recon = dataclasses.replace(carried, grasped=grasped)
    with pytest.raises(robot.PlanError):
        retargeting._plan_anywhere(robot.robot_reconstruction(recon)[0], None, True)
    plan = robot.retarget(recon)
    taken_over, _ = robot.robot_reconstruction(carried)  # where an object carried into view is taken
    np.testing.assert_allclose(plan.object_pos[0], taken_over.object_pos[0])
    assert robot.replay(plan, recon, engine="mujoco").success
