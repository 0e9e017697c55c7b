"""The Panda runs the skill in another layout: retarget(..., layout=), the plan carries it, replays simulate it."""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest
from robot_support import require_robot

robot = require_robot("placo", "mujoco")
from warpskill.cli import main  # noqa: E402
from warpskill.contract import Layout, LayoutError, Reconstruction, Skill  # noqa: E402
from warpskill.contract.replay import Replay  # noqa: E402
from warpskill.robot.skill_layout import demonstrated_layout, skill_from  # noqa: E402
from warpskill.synthetic import make_demonstration  # noqa: E402


@functools.cache
def truth(action: str, seed: int = 0) -> Reconstruction:
    """The ground truth of a synthetic demonstration (made once per test run; never modified)."""
    return Reconstruction(**make_demonstration(action, seed=seed, noise="none").truth)


def moved(layout: Layout, dx: float, dy: float, dyaw: float) -> Layout:
    """``layout`` with the object and the static boxes shifted by (dx, dy) [m] and turned by dyaw [rad]."""
    shift = lambda pose: (pose[0] + dx, pose[1] + dy, pose[2] + dyaw)  # noqa: E731
    return dataclasses.replace(layout, object=shift(layout.object), statics=tuple(map(shift, layout.statics)))


@pytest.mark.slow
def test_identity_layout_plans_exactly_as_the_reconstruction():
    recon = truth("push_left_to_right")
    plain = robot.retarget(recon)
    skill = skill_from(recon)
    for carried in (robot.retarget(recon, layout=demonstrated_layout(skill)), robot.retarget(skill)):
        assert carried.grasp_name == plain.grasp_name and carried.num_samples == plain.num_samples
        np.testing.assert_allclose(carried.q, plain.q, atol=1e-9)
        np.testing.assert_allclose(carried.base, plain.base, atol=1e-12)
        assert carried.layout == demonstrated_layout(skill)
    assert plain.layout is None


@pytest.mark.slow
@pytest.mark.parametrize("action, shift", [
    ("push_left_to_right", (0.08, 0.06, math.radians(35))),
    ("push_left_to_right", (-0.06, -0.03, math.radians(-90))),
    ("put_behind", (-0.06, -0.04, math.radians(30))),
    ("put_behind", (0.1, 0.0, 0.0)),
])
def test_moved_layouts_replay_successfully(action, shift):
    recon = truth(action)
    layout = moved(demonstrated_layout(skill_from(recon)), *shift)
    plan = robot.retarget(recon, layout=layout)
    result = robot.replay(plan, recon, engine="mujoco")
    assert result.success, result.evaluation.checks
    replayed = result.reconstruction  # the new layout's scene, as the replay recorded it
    np.testing.assert_allclose(replayed.object_pos[0, :2], layout.object[:2], atol=0.01)
    np.testing.assert_allclose(replayed.static_pos[:, :2], np.array(layout.statics).reshape(-1, 3)[:, :2], atol=1e-9)
    for rot, (_, _, yaw) in zip(replayed.static_rot, layout.statics):
        assert math.atan2(rot[1, 0], rot[0, 0]) == pytest.approx(yaw)


def test_out_of_reach_layout_is_refused():
    recon = truth("put_behind")
    layout = demonstrated_layout(skill_from(recon))
    far = dataclasses.replace(layout, object=(layout.object[0] + 1.6, *layout.object[1:]))
    with pytest.raises(LayoutError, match="layout refused: out of the Panda's reach") as error:
        robot.retarget(recon, layout=far)
    assert "\n" not in str(error.value)


def test_cli_refuses_an_impossible_layout_with_status_2(tmp_path, capsys):
    truth("put_behind").save(tmp_path / "recon.npz")
    status = main(["retarget", str(tmp_path / "recon.npz"), "-o", str(tmp_path / "plan.npz"),
                   "--object-at", "0.0", "0.6", "0", "--static-at", "0.1", "0.7", "0",
                   "--static-at", "0.3", "0.7", "0"])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1
    assert err.startswith("warpskill: error: layout refused: it places 2 static box(es), the put_behind skill has 1")
    assert not (tmp_path / "plan.npz").exists()


@pytest.mark.slow
def test_cli_retarget_and_replay_a_layout(tmp_path):
    recon = truth("push_left_to_right")
    recon.save(tmp_path / "recon.npz")
    x, y = recon.object_pos[0, :2] + (0.05, 0.04)
    assert main(["retarget", str(tmp_path / "recon.npz"), "-o", str(tmp_path / "plan.npz"),
                 "--object-at", str(x), str(y), "30"]) == 0
    plan = robot.RobotPlan.load(tmp_path / "plan.npz")
    assert demonstrated_layout(Skill.load(tmp_path / "skill.npz")) == demonstrated_layout(skill_from(recon))  # beside the reconstruction
    assert plan.layout.object == pytest.approx((x, y, math.radians(30)))
    assert main(["replay", str(tmp_path / "plan.npz"), str(tmp_path / "recon.npz"), "-o", str(tmp_path / "out")]) == 0
    replayed = Replay.load(tmp_path / "out" / "replay.npz")
    assert replayed.success
    np.testing.assert_allclose(replayed.reconstruction.object_pos[0, :2], (x, y), atol=0.01)
