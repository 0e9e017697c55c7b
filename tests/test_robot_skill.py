"""The Panda does the skill: it stands where it can (placement search), starts from home onto the
demonstrated path near the contact, and handles its own object sizes (substituting a too-wide one)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from robot_support import require_robot

robot = require_robot("placo", "mujoco")
from warpskill.cli import main  # noqa: E402
from warpskill.contract.reconstruction import Reconstruction  # noqa: E402
from warpskill.robot.model import make_scene  # noqa: E402
from warpskill.synthetic import make_demonstration  # noqa: E402

LOWER = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
UPPER = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])
SPEED = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
PLATE = (0.264, 0.234, 0.05)  # [m] a plate: wider than the gripper's opening on every face


def truth(action: str, seed: int) -> Reconstruction:
    return Reconstruction(**make_demonstration(action, seed=seed, noise="none").truth)


def assert_admissible(recon: Reconstruction, plan) -> None:
    """Within the joint position and speed limits, and no collision, at the plan's base and sizes."""
    from warpskill.robot.planner import Planner

    assert np.all(plan.q >= LOWER) and np.all(plan.q <= UPPER)
    speed = np.abs(np.diff(plan.q, axis=0)) / np.diff(plan.t)[:, None]
    assert np.all(speed <= SPEED * 1.001), speed.max(0)
    planner = Planner(make_scene(plan.scene(recon), base=plan.base))
    for q, opening in zip(plan.q[::3], plan.gripper[::3]):
        planner.set_q(q, opening)
        assert min(d.min_distance for d in planner.robot.distances()) > 0.0


def far_static(recon: Reconstruction, distance: float = 1.7) -> Reconstruction:
    """``recon`` with a static box ``distance`` to the object's right: the scene centre moves half of it away."""
    pos = recon.object_pos[0] + np.array([distance, 0.0, 0.0])
    pos[2] = 0.05
    return dataclasses.replace(recon, static_pos=pos[None], static_rot=np.eye(3)[None],
                               static_size=np.array([[0.1, 0.1, 0.1]]))


@pytest.mark.slow
def test_the_robot_stands_where_it_can_do_the_task():
    recon = far_static(truth("pick_up", 0))
    # At the default placement the cuboid lies 0.85 m to the side of the scene centre, about 1 m from
    # the base: out of the arm's reach.
    with pytest.raises(robot.PlanError):
        robot.retarget(recon, placement=robot.Placement())
    plan = robot.retarget(recon)
    assert plan.placement == "auto"
    assert not (np.allclose(plan.offset, robot.Placement().offset) and np.isclose(plan.yaw, robot.Placement().yaw))
    assert_admissible(recon, plan)
    assert robot.replay(plan, recon).success
    again = robot.retarget(recon)  # deterministic
    np.testing.assert_allclose(again.base, plan.base)


def test_the_hand_far_away_before_the_contact_never_fails_the_plan():
    recon = truth("push_left_to_right", 0)
    k_on = int(np.flatnonzero(recon.grasped > 0.5)[0])
    hand = recon.hand_pos.copy()
    # The person's hand starts 1.2 m away and high up, and only comes to the object just before the contact.
    fade = np.clip(1.0 - np.arange(recon.num_frames) / max(k_on - 5, 1), 0.0, 1.0)[:, None]
    hand += fade * np.array([-0.9, -0.6, 0.6])
    recon = dataclasses.replace(recon, hand_pos=hand)
    plan = robot.retarget(recon, placement=robot.Placement())
    assert_admissible(recon, plan)
    # The robot starts from home and is near the object (not out at the person's hand) when the demonstration starts.
    start = np.searchsorted(plan.t, plan.start_time)
    assert np.linalg.norm(plan.tcp[start, :3, 3] - recon.object_pos[k_on]) < 0.35
    from warpskill.robot.model import HOME_Q

    np.testing.assert_allclose(plan.q[0], HOME_Q, atol=0.1)
    assert robot.replay(plan, recon).success


def test_a_plate_wider_than_the_gripper_is_substituted_and_picked_up(tmp_path):
    recon = truth("pick_up", 0)
    plan = robot.retarget(recon, object_size=PLATE)
    assert "wider than the gripper's 0.074 m usable opening" in plan.note
    assert plan.object_size[2] == pytest.approx(PLATE[2])  # height kept
    assert np.all(plan.object_size[:2] <= 0.074)  # the horizontal extents fit the gripper
    # The demonstrated centre path is kept; the thin object rests on the table at the start.
    np.testing.assert_allclose(plan.object_pos[:, :2], recon.object_pos[:, :2])
    vertical = np.abs(recon.object_rot[0, 2])  # the cuboid's axes' share of the vertical
    lowest = plan.object_pos[0, 2] - 0.5 * vertical @ plan.object_size
    assert lowest == pytest.approx(recon.object_pos[0, 2] - 0.5 * vertical @ recon.object_size, abs=1e-6)
    assert_admissible(recon, plan)
    result = robot.replay(plan, recon)
    assert result.success, result.evaluation.checks
    result.save(tmp_path / "replay.npz")
    with np.load(tmp_path / "replay.npz") as saved:  # the sizes as simulated
        np.testing.assert_allclose(saved["object_size"], plan.object_size)
    with pytest.raises(robot.PlanError, match="wider than the gripper's 0.074 m usable opening"):
        robot.retarget(recon, object_size=PLATE, keep_size=True)


def test_wide_pushes_need_no_substitute():
    recon = truth("push_left_to_right", 0)
    plan = robot.retarget(recon, object_size=(0.26, 0.23, 0.05), placement=robot.Placement())
    assert plan.note == "" and plan.grasp_kind == "push"
    np.testing.assert_allclose(plan.object_size, (0.26, 0.23, 0.05))


def test_static_sizes_move_the_resting_heights():
    from warpskill.robot import fit_sizes

    recon = truth("put_onto", 0)
    taller = recon.static_size.copy()
    taller[0, 2] += 0.04
    fitted, note = fit_sizes(recon, static_sizes=taller, keep_size=True)
    assert note == ""
    assert fitted.static_pos[0, 2] == pytest.approx(recon.static_pos[0, 2] + 0.02)  # its bottom stays on the table
    assert fitted.object_pos[0, 2] == pytest.approx(recon.object_pos[0, 2])  # starts on the table
    assert fitted.object_pos[-1, 2] == pytest.approx(recon.object_pos[-1, 2] + 0.04)  # ends on the taller top
    with pytest.raises(ValueError, match="static size"):
        fit_sizes(recon, static_sizes=[(0.1, 0.1, 0.1)] * 2)


def test_cli_object_size_and_keep_size(tmp_path, capsys):
    recon = truth("pick_up", 0)
    recon.save(tmp_path / "recon.npz")
    args = ["retarget", str(tmp_path / "recon.npz"), "-o", str(tmp_path / "plan.npz"), "--object-size", *map(str, PLATE)]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "placement (auto)" in out
    assert sum("wider than the gripper's 0.074 m usable opening" in line for line in out.splitlines()) == 1
    assert main(["replay", str(tmp_path / "plan.npz"), str(tmp_path / "recon.npz"), "-o", str(tmp_path / "out")]) == 0
    with np.load(tmp_path / "out" / "replay.npz") as saved:
        np.testing.assert_allclose(saved["object_size"], robot.RobotPlan.load(tmp_path / "plan.npz").object_size)
    assert main([*args, "--keep-size"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("warpskill: error: frame") and err.count("\n") == 1
    assert "no feasible grasp: the 0.264 x 0.234 x 0.050 m cuboid is wider than the gripper's 0.074 m" in err


@pytest.mark.parametrize("degrees", [20.0, 5.0])  # a clear tilt, and one that stood a tall pillar on its edge
def test_a_tilted_cuboid_rests_on_a_face(degrees):
    from warpskill.geometry import cuboid_corners
    from warpskill.robot import fit_sizes

    recon = truth("push_right_to_left", 0)
    a = np.radians(degrees)
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])
    tilted = dataclasses.replace(recon, object_rot=tilt @ recon.object_rot)
    fitted, note = fit_sizes(tilted)
    assert note == ""
    corners = cuboid_corners(fitted.object_pos[0], fitted.object_rot[0], fitted.object_size)
    lowest = np.sort(corners[:, 2])[:4]
    np.testing.assert_allclose(lowest, lowest[0], atol=1e-9)  # a face down
    before = cuboid_corners(tilted.object_pos[0], tilted.object_rot[0], tilted.object_size)[:, 2].min()
    assert lowest[0] == pytest.approx(before, abs=1e-9)  # on the same support
    np.testing.assert_allclose(fitted.object_pos[:, :2], tilted.object_pos[:, :2])


def test_placements_are_ranked_short_of_full_stretch():
    from warpskill.robot.placement import COMFORT_REACH, REACH, SHOULDER, WRIST, reach_excess

    def key(distance: float) -> np.ndarray:
        """A top-down TCP pose whose wrist centre lies ``distance`` ahead of the shoulder, at its height."""
        T = np.eye(4)
        T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # approach (local z) straight down
        T[:3, 3] = (distance, 0.0, SHOULDER - WRIST)
        return T

    base = np.eye(4)
    assert reach_excess(base, [[key(0.75)]]) == 0.0  # within the arm's reach ...
    # ... but not comfortably:
    assert reach_excess(base, [[key(0.75)]], COMFORT_REACH) == pytest.approx(0.75 - COMFORT_REACH)
    assert reach_excess(base, [[key(REACH + 0.05)]]) == pytest.approx(0.05)
    assert reach_excess(base, [[key(0.75)], [key(0.6)]], COMFORT_REACH) == 0.0  # the best grasp pose's


def test_open_fingers_beside_the_object_count_as_near_it_where_the_tcp_alone_is_clear():
    from warpskill.robot.targets import OBJECT_CLEARANCE, _fingers_near_object

    recon = truth("pick_up", 0)
    top = float(recon.object_pos[0, 2] + 0.5 * recon.object_size[2])
    side = recon.object_rot[0][:, 0]  # the object's local x, horizontal
    beside = np.eye(4)
    beside[:3, 2] = [0.0, 0.0, -1.0]  # pointing down
    beside[:3, 3] = recon.object_pos[0] + side * (0.5 * recon.object_size[0] + OBJECT_CLEARANCE + 0.015)
    beside[2, 3] = top - 0.01  # the finger tips below the object's top
    # Fingers opening towards the object reach 4 cm from the TCP: into the clearance.
    beside[:3, 1] = side
    beside[:3, 0] = np.cross(beside[:3, 1], beside[:3, 2])
    assert _fingers_near_object(recon, beside, 0.08)
    assert not _fingers_near_object(recon, beside, 0.0)  # closed, the TCP is 1.5 cm beyond the clearance
    # Opening along the object's face, the fingers stay as far from it as the TCP.
    along = beside.copy()
    along[:3, 1] = np.cross(along[:3, 2], side)
    along[:3, 0] = np.cross(along[:3, 1], along[:3, 2])
    assert not _fingers_near_object(recon, along, 0.08)
    # High above the object's top (more than the fingers' length plus the clearance), nothing is near.
    above = beside.copy()
    above[:3, 3] = recon.object_pos[0]
    above[2, 3] = top + OBJECT_CLEARANCE + 0.01
    assert not _fingers_near_object(recon, above, 0.08)
    above[2, 3] = top + OBJECT_CLEARANCE - 0.01
    assert _fingers_near_object(recon, above, 0.08)


def test_the_robot_never_follows_a_hand_path_through_the_object():
    from warpskill.robot.targets import APPROACH_TIME, OBJECT_CLEARANCE

    recon = truth("pull_left_to_right", 0)
    first = robot.retarget(recon, placement=robot.Placement())
    pregrasp = first.tcp[np.searchsorted(first.t, first.grasp_time - APPROACH_TIME), :3, 3]
    # The robot follows the demonstrated hand path shifted to end at the pre-grasp; here that
    # shifted path passes through the object's centre shortly before (the physics lets a
    # reconstructed hand pass through the object before the contact).
    t_pre = first.recon_time[np.searchsorted(first.t, first.grasp_time - APPROACH_TIME)]
    k_pre = int(np.floor(t_pre * float(recon.fps)))
    hand = recon.hand_pos.copy()
    hand[k_pre - 4: k_pre - 1] = hand[k_pre] + recon.object_pos[0] - pregrasp
    recon = dataclasses.replace(recon, hand_pos=hand)
    plan = robot.retarget(recon, placement=robot.Placement())
    assert plan.grasp_name == first.grasp_name
    scene = plan.scene(recon)
    before = (plan.t >= plan.start_time) & (plan.t < plan.grasp_time - APPROACH_TIME)
    local = (plan.tcp[before, :3, 3] - scene.object_pos[0]) @ scene.object_rot[0]
    outside = np.any(np.abs(local) >= 0.5 * scene.object_size + OBJECT_CLEARANCE - 1e-3, axis=1)
    assert before.any() and outside.all()
    assert robot.replay(plan, recon).success
