"""Retargeting to the Panda: plans respect joint limits and avoid collisions; bad inputs fail clearly."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from robot_support import require_robot

robot = require_robot("placo")
from warpskill.contract.reconstruction import Reconstruction  # noqa: E402
from warpskill.robot.model import (  # noqa: E402
    make_scene,
    panda_description_dir,
    panda_urdf,
)
from warpskill.synthetic import make_demonstration  # noqa: E402

# URDF limits of the Panda arm (panda.urdf of example-robot-data).
LOWER = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
UPPER = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])
SPEED = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])

# pull_right_to_left 0: the cuboid is too wide to grasp, the gripper hooks it; push_right_to_left 0: the
# start violates the hard collision margin and is softened; put_next_to 0: set down beside a taller box,
# closer to it than a finger is thick.
# put_onto 0: the cuboid is too wide to grasp: a substitute that fits is planned.
CASES = [("pick_up", 0), ("push_left_to_right", 0), ("pull_right_to_left", 0), ("push_right_to_left", 0),
         ("put_next_to", 0), ("put_onto", 0)]


def truth(action: str, seed: int) -> Reconstruction:
    return Reconstruction(**make_demonstration(action, seed=seed, noise="none").truth)


@pytest.fixture(scope="module")
def plans():
    return {case: (truth(*case), robot.retarget(truth(*case))) for case in CASES}


def test_urdf_paths_resolved():
    for kind in ("primitives", "meshes"):
        text = panda_urdf(collision=kind)
        assert "package://" not in text
    assert (panda_description_dir() / "meshes" / "collision" / "link0.stl").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES)
def test_plan_within_joint_limits(plans, case):
    _, plan = plans[case]
    assert plan.q.shape == (plan.num_samples, 7)
    assert np.all(plan.q >= LOWER) and np.all(plan.q <= UPPER)
    speed = np.abs(np.diff(plan.q, axis=0)) / np.diff(plan.t)[:, None]
    assert np.all(speed <= SPEED * 1.001), speed.max(0)
    assert np.all((plan.gripper >= 0) & (plan.gripper <= 0.08))


@pytest.mark.parametrize("case", CASES)
def test_plan_has_no_self_or_table_collision(plans, case):
    from warpskill.robot.planner import Planner

    recon, plan = plans[case]
    planner = Planner(make_scene(plan.scene(recon), base=plan.base))  # the chosen base, the objects as handled
    for q, opening in zip(plan.q[::2], plan.gripper[::2]):
        planner.set_q(q, opening)
        closest = min(d.min_distance for d in planner.robot.distances())
        assert closest > 0.0


def test_plan_events_and_tcp(plans):
    recon, plan = plans[("pick_up", 0)]
    assert plan.grasp_kind == "grasp" and np.isfinite(plan.grasp_time) and np.isnan(plan.release_time)
    # Once the gripper has closed it stays closed (pick_up never releases).
    held = plan.t > plan.grasp_time + 0.6
    assert np.all(plan.gripper[held] == 0.0)
    start = np.searchsorted(plan.t, plan.start_time)
    assert abs(plan.recon_time[start]) < 1e-9


def test_plan_save_load_csv(plans, tmp_path):
    _, plan = plans[("push_left_to_right", 0)]
    plan.save(tmp_path / "plan.npz")
    plan.save_csv(tmp_path / "plan.csv")
    again = robot.RobotPlan.load(tmp_path / "plan.npz")
    np.testing.assert_allclose(again.q, plan.q)
    assert again.grasp_name == plan.grasp_name and again.grasp_kind == "push"
    lines = (tmp_path / "plan.csv").read_text().splitlines()
    assert lines[0].startswith("t,q1,") and len(lines) == plan.num_samples + 1


def test_infeasible_grasp_names_frame():
    recon = truth("put_onto", 0)  # a 0.096 x 0.097 x 0.061 m box: wider than the gripper on every face
    with pytest.raises(robot.PlanError, match=r"frame 15 .*no feasible grasp.*wider than the gripper's 0.074 m"):
        robot.retarget(recon, keep_size=True)


@pytest.mark.slow
def test_unreachable_target_names_frame():
    recon = truth("pick_up", 0)
    lifted = recon.object_pos.copy()
    k = np.flatnonzero(recon.grasped > 0.5)
    lifted[k[-10:], 2] += 1.5  # the object (and so the gripper) would have to fly 1.5 m up
    recon.object_pos = lifted
    with pytest.raises(robot.PlanError, match=r"frame \d+ \(t = .* s\): the gripper cannot reach"):
        robot.retarget(recon)


def test_wide_cuboid_is_pulled_with_a_hook(plans):
    plan = plans[("pull_right_to_left", 0)][1]
    assert plan.grasp_name.startswith("hook_") and plan.grasp_kind == "push"
    assert np.all(plan.gripper == 0.0)


def test_set_down_beside_a_taller_box_leaves_room_for_the_fingers(plans):
    recon, plan = plans[("put_next_to", 0)]
    assert plan.grasp_kind == "grasp" and np.isfinite(plan.release_time)
    # The deep grasp would put the hand on the static box: a shallow one, moved away from the box if needed.
    assert plan.grasp_name.endswith("_shallow")
    released = np.searchsorted(plan.t, plan.release_time)
    k_off = np.flatnonzero(recon.grasped > 0.5)[-1] + 1
    static = recon.static_pos[0]
    demo_gap = np.linalg.norm(recon.object_pos[k_off, :2] - static[:2])
    planned_gap = np.linalg.norm(_object_at(plan, released)[:2] - static[:2])
    # Never nearer the box than demonstrated, at most 5 cm further.
    assert demo_gap - 2e-3 <= planned_gap <= demo_gap + 0.05 + 2e-3
    # Set down where the demonstration sets it down: on the table, not dropped from above.
    assert abs(_object_at(plan, released)[2] - recon.object_pos[k_off, 2]) < 0.006


def _object_at(plan, i):
    """The object's centre [m] implied by the planned TCP pose at sample ``i``."""
    return (plan.tcp[i] @ np.linalg.inv(plan.grasp_pose))[:3, 3]


def test_a_carried_cuboid_keeps_its_grasp_orientation(plans):
    from warpskill.robot.planner import rotation_error_deg as _rotation_error_deg

    recon, plan = plans[("pick_up", 0)]
    turned = recon.object_rot.copy()
    angles = np.linspace(0.0, 1.5, recon.num_frames)  # the reconstruction spins the object in the hand
    for k, a in enumerate(angles):
        c, s = np.cos(a), np.sin(a)
        turned[k] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ recon.object_rot[k]
    spun = robot.retarget(dataclasses.replace(recon, object_rot=turned))
    hold = np.flatnonzero(spun.phases() == "hold")
    assert len(hold) > 10
    # The gripper carries the cuboid upright along its path: no turn of the TCP while holding.
    assert max(_rotation_error_deg(spun.tcp[hold[0], :3, :3], spun.tcp[i, :3, :3]) for i in hold) < 3.0
    np.testing.assert_allclose(spun.tcp[hold[-1], :2, 3], plan.tcp[np.flatnonzero(plan.phases() == "hold")[-1], :2, 3],
                               atol=0.02)


def test_push_poses_face_the_way_the_object_moves():
    from warpskill.robot.grasps import candidate_poses, rank_poses

    poses = candidate_poses(np.eye(3), np.array([0.06, 0.06, 0.06]), push_height=0.0, pushing=True)
    from_front = np.array([0.0, -1.0, 0.6]) / np.linalg.norm([0.0, -1.0, 0.6])  # the hand's axis: the arm is in front
    moving_left = rank_poses(poses, np.eye(3), from_front, push_direction=np.array([-1.0, 0.0, 0.0]))
    assert moving_left and all(pose.name.startswith("push_+x") for _, pose in moving_left)
    moving_back = rank_poses(poses, np.eye(3), from_front, push_direction=np.array([0.0, 1.0, 0.0]))
    assert moving_back and all(pose.name.startswith("push_-y") for _, pose in moving_back)


def test_a_push_presses_the_face_most_square_to_the_motion():
    from warpskill.robot.grasps import candidate_poses, rank_poses

    turn = np.radians(148.0)  # the cuboid turned 148 deg: one face's normal is 32 deg off the motion, one 58 deg
    R = np.array([[np.cos(turn), -np.sin(turn), 0.0], [np.sin(turn), np.cos(turn), 0.0], [0.0, 0.0, 1.0]])
    poses = candidate_poses(R, np.array([0.055, 0.074, 0.09]), push_height=0.0, pushing=True)
    # The demonstrated hand came in along the 58-deg face's normal (from the front left, tilted down).
    hand_axis = np.array([-0.53, -0.848, 0.8])
    ranked = rank_poses(poses, R, hand_axis, push_direction=np.array([1.0, 0.0, 0.0]))

    def slant(pose):  # [deg] between the pose's horizontal approach and the motion (+x)
        approach = R @ pose.pose[:3, 2]
        return np.degrees(np.arccos(approach[0] / np.linalg.norm(approach[:2])))

    assert {round(slant(pose)) for _, pose in ranked} == {32, 58}
    assert round(slant(ranked[0][1])) == 32


def test_a_thin_object_is_pushed_by_the_fingertips_above_the_table():
    from warpskill.robot.grasps import FINGERTIP_BELOW_TCP, candidate_poses

    size = np.array([0.20, 0.13, 0.02])  # a plate
    for pose in candidate_poses(np.eye(3), size, push_height=0.0, pushing=True):
        tcp, approach = pose.pose[:3, 3], pose.pose[:3, 2]
        fingertip = tcp + FINGERTIP_BELOW_TCP * approach
        assert fingertip[2] < size[2] / 2, pose.name  # below the top face: the pads press its side
        assert fingertip[2] > -size[2] / 2, pose.name  # above the table


def test_a_thin_object_is_grasped_as_low_as_the_table_allows():
    from warpskill.robot.grasps import FINGERTIP_BELOW_TCP, TABLE_CLEARANCE, TOP_DEPTH, candidate_poses

    for height in (0.014, 0.02, 0.1):  # a pen, a phone, a box
        size = np.array([0.15, 0.04, height])
        tops = [pose for pose in candidate_poses(np.eye(3), size) if pose.name in ("top_y", "top_y_flip")]
        assert tops
        for pose in tops:
            fingertip = pose.pose[2, 3] - FINGERTIP_BELOW_TCP  # pointing down: along -z
            # As deep as the grasp goes (TOP_DEPTH below the top), never closer to the table than the clearance.
            assert fingertip == pytest.approx(max(height / 2 - TOP_DEPTH - FINGERTIP_BELOW_TCP,
                                                  -height / 2 + TABLE_CLEARANCE), abs=1e-9), (height, pose.name)


@pytest.mark.parametrize("action", ["push_left_to_right", "push_right_to_left"])
def test_the_lead_in_passes_over_a_tall_object_without_knocking_it_over(action):
    require_robot("mujoco")
    from warpskill.robot.replay_mujoco import simulate

    recon = truth(action, 0)
    size = recon.object_size.copy()
    size[2] = 0.5  # a 50 cm pillar: its top is above the home pose's TCP
    pos = recon.object_pos.copy()
    pos[:, 2] += (size[2] - recon.object_size[2]) / 2
    tall = dataclasses.replace(recon, object_size=size, object_pos=pos)
    plan = robot.retarget(tall)
    scene = plan.scene(tall)
    sim = simulate(plan, scene, np.array([plan.t[0], plan.start_time]))
    # Before the demonstration starts the robot has only moved from home to where it joins it.
    assert np.abs(sim["object_pos"][1] - sim["object_pos"][0]).max() < 0.005
