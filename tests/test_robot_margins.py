"""No plan lost to a few centimetres: the reach margin over the whole path, and a put onto's checked release."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
from robot_support import require_robot

robot = require_robot("placo", "mujoco")
from warpskill.contract import LayoutError, Reconstruction  # noqa: E402
from warpskill.export.layouts import sample_layouts  # noqa: E402
from warpskill.geometry import cuboid_corners  # noqa: E402
from warpskill.robot.model import make_scene  # noqa: E402
from warpskill.robot.placement import (  # noqa: E402
    REACH,
    REACH_MARGIN,
    WRIST,
    candidate_placements,
    check_reach,
    path_shortfall,
    path_wrists,
)
from warpskill.robot.replaying import RELEASE_CHECK, release_checks  # noqa: E402
from warpskill.robot.skill_layout import SWING_SPEED, apply_skill, demonstrated_layout, skill_from, takeover  # noqa: E402
from warpskill.robot.targets import ONTO_CLEARANCE  # noqa: E402
from warpskill.synthetic import make_demonstration  # noqa: E402


@functools.cache
def truth(action: str, seed: int = 0) -> Reconstruction:
    """The ground truth of a synthetic demonstration (made once per test run; never modified)."""
    return Reconstruction(**make_demonstration(action, seed=seed, noise="none").truth)


def raised(recon: Reconstruction, dz: float) -> Reconstruction:
    """``recon`` with the held object (and the hand) raised by up to ``dz`` [m], linearly from the
    grasp onset to the last frame."""
    held = np.flatnonzero(recon.grasped > 0.5)
    lift = np.zeros(recon.num_frames)
    lift[held[0]:] = dz * np.linspace(0.0, 1.0, recon.num_frames - held[0])
    object_pos, hand_pos = recon.object_pos.copy(), recon.hand_pos.copy()
    object_pos[:, 2] += lift
    hand_pos[:, 2] += lift
    return dataclasses.replace(recon, object_pos=object_pos, hand_pos=hand_pos)


def best_shortfall(recon: Reconstruction, margin: float) -> float:
    """The least :func:`path_shortfall` [m] over the candidate placements (0: some keeps ``margin``)."""
    _, wrists = path_wrists(recon)
    return min(path_shortfall(make_scene(recon, p).base, wrists, margin)[0] for p in candidate_placements())


def lift_into_margin(recon: Reconstruction) -> Reconstruction:
    """The pick-up raised until its path, from the best placement, lies inside the arm's reach
    but within the margin of its limit (bisection on the lift)."""
    lo, hi = 0.0, 1.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if best_shortfall(raised(recon, mid), REACH_MARGIN) == 0.0 else (lo, mid)
    into = raised(recon, hi + 0.5 * REACH_MARGIN)  # halfway into the margin
    assert best_shortfall(into, REACH_MARGIN) > 0.0 and best_shortfall(into, 0.0) == 0.0
    return into


def test_a_path_that_runs_into_the_reach_margin_is_refused_with_a_reason():
    """Within the arm's reach at every frame, but closer than the margin to its limit: a layout is
    refused before planning, naming the frame, how far into the margin and the margin."""
    near = lift_into_margin(truth("pick_up"))
    with pytest.raises(LayoutError, match=r"out of the Panda's reach: .* runs \d+\.\d cm into the 5 cm margin "
                                          r"kept inside the arm's 0\.80 m reach and 0\.25 m from its base \(frame \d+, t = "):
        check_reach(near)
    skill = skill_from(near)
    with pytest.raises(LayoutError, match="into the 5 cm margin"):
        robot.retarget(skill)  # the skill in its own layout: refused, one line, no plan
    check_reach(truth("pick_up"))  # the demonstration itself keeps the margin


@pytest.mark.slow
def test_the_placement_keeps_the_margin_over_the_whole_held_path():
    """A pick-up lifted so high that the default base would carry it within the margin of the
    reach limit: the plan stands where every held sample keeps the margin."""
    recon = truth("pick_up")
    default = make_scene(recon).base
    dz = 0.0
    while path_shortfall(default, path_wrists(raised(recon, dz))[1])[0] == 0.0:
        dz += 0.01
    high = raised(recon, dz + 0.02)  # the default's path now runs 2-3 cm into the margin ...
    assert best_shortfall(high, REACH_MARGIN) == 0.0  # ... but another placement keeps it
    plan = robot.retarget(high)
    assert not np.allclose(plan.base, default)
    held = plan.t >= plan.grasp_time
    shoulder = plan.base[:3, 3] + 0.333 * plan.base[:3, 2]
    wrists = plan.tcp[held, :3, 3] - WRIST * plan.tcp[held, :3, 2]
    assert np.linalg.norm(wrists - shoulder, axis=1).max() <= REACH - REACH_MARGIN + 0.01
    result = robot.replay(plan, high)
    assert result.success, result.evaluation.checks


def test_layouts_drawn_keep_the_margin():
    skill = skill_from(truth("put_behind"))
    for layout in sample_layouts(skill, 5, seed=3):
        check_reach(apply_skill(skill, layout))  # raises where a drawn path would run into the margin


def test_an_object_swung_into_view_starts_a_layout_where_it_has_slowed_down():
    recon = truth("put_behind")
    held = np.flatnonzero(recon.grasped > 0.5)
    grasped = recon.grasped.copy()
    grasped[: held[0]] = 1.0  # carried into view ...
    object_pos = recon.object_pos.copy()
    swing = np.linspace(2.0, 0.0, held[0] + 1)[:-1]  # ... from 2 m away, fast
    object_pos[: held[0], 1] += swing
    object_pos[: held[0], 2] += 0.2
    carried = dataclasses.replace(recon, grasped=grasped, object_pos=object_pos)
    skill = skill_from(carried)
    k = takeover(skill)
    assert k == held[0]
    speed = np.linalg.norm(np.diff(object_pos, axis=0), axis=1) * recon.fps
    assert speed[k - 1] > SWING_SPEED and np.all(speed[k:held[-1]] <= SWING_SPEED)
    np.testing.assert_allclose(demonstrated_layout(skill).object[:2], recon.object_pos[k, :2], atol=1e-9)
    layout = sample_layouts(skill, 1, seed=0)[0]  # the 2 m swing is not part of a layout's path
    applied = apply_skill(skill, layout)
    assert np.ptp(applied.object_pos[:k], axis=0).max() == 0.0  # it waits there, resting on the table
    assert applied.object_corners()[0, :, 2].min() == pytest.approx(0.0, abs=1e-9)
    assert takeover(skill_from(applied)) == 0  # the layout's reconstruction starts still


@pytest.fixture(scope="module")
def put_onto():
    recon = truth("put_onto")
    plan = robot.retarget(recon)
    return recon, plan, robot.replay(plan, recon)


def test_a_put_onto_releases_its_own_size_above_the_static_top(put_onto):
    recon, plan, _ = put_onto
    scene = plan.scene(recon)  # the robot's cuboids (here a substitute that fits the gripper)
    i = int(np.searchsorted(plan.t, plan.release_time))
    T_obj = plan.tcp[i] @ np.linalg.inv(plan.grasp_pose)  # where the planned gripper holds the object
    bottom = cuboid_corners(T_obj[:3, 3], T_obj[:3, :3], scene.object_size)[:, 2].min()
    top = scene.static_corners()[0, :, 2].max()
    assert bottom == pytest.approx(top + ONTO_CLEARANCE, abs=0.005)
    local = scene.static_rot[0].T @ (T_obj[:3, 3] - scene.static_pos[0])
    assert np.all(np.abs(local[:2]) < scene.static_size[0, :2] / 2)


def test_the_replay_checks_the_put_onto_release(put_onto):
    _, _, result = put_onto
    assert result.evaluation.checks[RELEASE_CHECK] and result.success


def test_a_release_off_the_static_top_is_a_failure_with_its_reason():
    """A plan that sets the object down beside the box, judged as a put onto: the replay reports
    the release off the top as a failed check, not a success."""
    beside = truth("put_next_to")
    plan = robot.retarget(beside)
    as_onto = dataclasses.replace(beside, action="put_onto")
    result = robot.replay(plan, as_onto)
    assert not result.success
    assert result.evaluation.checks[RELEASE_CHECK] is False
    replayed = result.reconstruction
    times = np.arange(replayed.num_frames) / replayed.fps
    assert release_checks(replayed, times, plan.release_time - plan.start_time) == {RELEASE_CHECK: False}


def test_a_put_onto_demonstrated_beside_the_box_is_released_on_its_top():
    """A reconstruction that ends the object just beside the box it was put onto: the robot
    releases it on the top (inside the footprint), and the replay confirms it."""
    recon = truth("put_onto")
    k_off = int(np.flatnonzero(recon.grasped > 0.5)[-1]) + 1
    ramp = np.clip((np.arange(recon.num_frames) - (k_off - 10)) / 10.0, 0.0, 1.0)  # over the last 10 held frames
    R, centre = recon.static_rot[0], recon.static_pos[0]
    beyond = centre + R[:, 0] * (recon.static_size[0, 0] / 2 + 0.01)  # the centre 1 cm beyond the top's edge
    off = np.outer(ramp, beyond - recon.object_pos[k_off])
    off[:, 2] = 0.0
    object_pos, hand_pos = recon.object_pos + off, recon.hand_pos + off
    edge = dataclasses.replace(recon, object_pos=object_pos, hand_pos=hand_pos)
    plan = robot.retarget(edge)
    result = robot.replay(plan, edge)
    assert result.evaluation.checks["over_static"] and result.evaluation.checks[RELEASE_CHECK], \
        result.evaluation.checks
