"""The Panda's forward kinematics and collision shapes (warpskill.robot.kinematics), against
placo (Pinocchio), the MuJoCo replay and the mesh files themselves."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from warpskill.cli.common import installed
from warpskill.robot.kinematics import link_poses, link_shapes

if importlib.util.find_spec("mujoco") is None or not installed("example-robot-data"):
    pytest.skip("needs mujoco and example-robot-data", allow_module_level=True)

from warpskill.robot.model import ARM_JOINTS, FINGER_JOINTS, HOME_Q, panda_description_dir, panda_urdf

LINKS = [f"panda_link{i}" for i in range(9)] + ["panda_hand", "panda_hand_tcp", "panda_leftfinger", "panda_rightfinger"]


def _base(yaw: float = 0.7, xyz=(0.3, -0.4, 0.02)) -> np.ndarray:
    T = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = xyz
    return T


def _random_q(count: int, seed: int = 0) -> np.ndarray:
    lo = np.array([-2.8, -1.7, -2.8, -3.0, -2.8, 0.0, -2.8])
    hi = np.array([2.8, 1.7, 2.8, -0.1, 2.8, 3.7, 2.8])
    return np.random.default_rng(seed).uniform(lo, hi, size=(count, 7))


def test_every_link_is_a_rigid_pose_and_the_base_carries_them():
    q = _random_q(5)
    gripper = np.linspace(0.0, 0.08, 5)
    poses = link_poses(q, gripper, _base())
    assert sorted(poses) == sorted(LINKS)
    at_origin = link_poses(q, gripper)
    for name, T in poses.items():
        assert T.shape == (5, 4, 4), name
        R = T[:, :3, :3]
        assert np.allclose(R @ np.swapaxes(R, 1, 2), np.eye(3), atol=1e-12), name
        assert np.allclose(T[:, 3], [0, 0, 0, 1]), name
        assert np.allclose(T, _base() @ at_origin[name], atol=1e-12), name
    assert np.allclose(poses["panda_link0"], _base())
    # The fingers open symmetrically by half the opening each, along the hand's y axis.
    hand_inv = np.linalg.inv(poses["panda_hand"])
    left = (hand_inv @ poses["panda_leftfinger"])[:, :3, 3]
    right = (hand_inv @ poses["panda_rightfinger"])[:, :3, 3]
    assert np.allclose(left[:, 1] - right[:, 1], gripper, atol=1e-12)


def test_one_configuration_and_bad_shapes():
    single = link_poses(HOME_Q, 0.08)
    assert single["panda_hand_tcp"].shape == (4, 4)
    # The SRDF's default pose: the gripper above the table, pointing down.
    tcp = single["panda_hand_tcp"]
    assert tcp[2, 3] > 0.3 and np.allclose(tcp[:3, 2], [0, 0, -1], atol=1e-3)
    with pytest.raises(ValueError, match="q"):
        link_poses(np.zeros((3, 6)))
    with pytest.raises(ValueError, match="gripper"):
        link_poses(np.zeros((3, 7)), np.zeros(2))
    with pytest.raises(ValueError, match="base"):
        link_poses(np.zeros((3, 7)), base=np.eye(3))


def test_link_poses_agree_with_placo():
    """Pinocchio (placo's robot model, the planner's) reads the same URDF to the same frames."""
    placo = pytest.importorskip("placo")
    robot = placo.RobotWrapper("", 0, panda_urdf(collision="primitives"))
    base = _base()
    robot.set_T_world_fbase(base)
    q = _random_q(4, seed=1)
    gripper = np.array([0.0, 0.02, 0.05, 0.08])
    poses = link_poses(q, gripper, base)
    for k in range(len(q)):
        for name, value in zip(ARM_JOINTS, q[k]):
            robot.set_joint(name, float(value))
        for name in FINGER_JOINTS:
            robot.set_joint(name, float(gripper[k] / 2))
        robot.update_kinematics()
        for link in LINKS:
            assert np.allclose(poses[link][k], robot.get_T_world_frame(link), atol=1e-9), (k, link)


@pytest.fixture(scope="module")
def robot_run():
    if importlib.util.find_spec("placo") is None:
        pytest.skip("needs placo")
    from warpskill.contract.reconstruction import Reconstruction
    from warpskill.robot.replaying import replay
    from warpskill.robot.retargeting import retarget
    from warpskill.synthetic import make_demonstration

    demo = make_demonstration("pick_up", seed=0, noise="none", image_size=(60, 80), fps=6.0, duration=3.0)
    recon = Reconstruction(**demo.truth)
    plan = retarget(recon)
    return recon, plan, replay(plan, recon)


def test_link_poses_are_the_mujoco_replays(robot_run):
    """Exactly the replay model's body poses for the same joints; the replay's sampled TCP to a mm."""
    import mujoco

    from warpskill.robot.replay_mujoco import build_model

    recon, plan, result = robot_run
    F = result.reconstruction.num_frames
    times = plan.start_time + np.arange(F) / float(recon.fps)
    gripper = np.interp(times, plan.t, plan.gripper)
    poses = link_poses(result.joints, gripper, plan.base)
    model = build_model(plan, recon)
    data = mujoco.MjData(model)
    arm = [model.joint(name).qposadr[0] for name in ARM_JOINTS]
    fingers = [model.joint(name).qposadr[0] for name in FINGER_JOINTS]
    for k in range(0, F, 3):
        data.qpos[arm] = result.joints[k]
        data.qpos[fingers] = gripper[k] / 2
        mujoco.mj_kinematics(model, data)
        for link in LINKS:
            body = model.body(link).id
            assert np.allclose(poses[link][k, :3, 3], data.xpos[body], atol=1e-12), (k, link)
            assert np.allclose(poses[link][k, :3, :3], data.xmat[body].reshape(3, 3), atol=1e-12), (k, link)
    # The replay reads MuJoCo's body poses one 2 ms physics step behind its joints: mm, not exact.
    tcp = poses["panda_hand_tcp"]
    assert np.abs(tcp[:, :3, 3] - result.reconstruction.hand_pos).max() < 1e-3
    hand_rot = tcp[:, :3, :3] @ np.diag([1.0, -1.0, -1.0])  # TCP frame -> hand frame of docs/formats.md
    assert np.abs(hand_rot - result.reconstruction.hand_rot).max() < 1e-2


def test_link_shapes_are_the_collision_meshes_in_link_frames():
    trimesh = pytest.importorskip("trimesh")
    shapes = link_shapes()
    assert set(shapes) == set(LINKS)
    files = {f"panda_link{i}": f"link{i}.stl" for i in range(8)} | {"panda_hand": "hand.stl"}
    for link, name in files.items():
        [shape] = shapes[link]
        assert shape.kind == "mesh" and shape.pose.shape == (4, 4), link
        assert shape.triangles.shape[1] == 3 and shape.triangles.max() < len(shape.vertices), link
        # The shape's vertices, placed by its pose, are the file's vertices in the link frame.
        placed = shape.vertices @ shape.pose[:3, :3].T + shape.pose[:3, 3]
        expected = np.asarray(trimesh.load(panda_description_dir() / "meshes" / "collision" / name).vertices)
        distance = np.linalg.norm(placed[:, None] - expected[None], axis=-1)
        assert distance.min(axis=1).max() < 1e-6 and distance.min(axis=0).max() < 1e-6, link
        # Outward triangles: the signed volume is positive.
        a, b, c = (shape.vertices[shape.triangles[:, i]] for i in range(3))
        assert np.einsum("ij,ij->i", a, np.cross(b, c)).sum() > 0, link
    for finger in ("panda_leftfinger", "panda_rightfinger"):
        assert [s.kind for s in shapes[finger]] == ["box"] * 4
        assert all(s.vertices is None and np.all(s.size > 0) for s in shapes[finger])
    assert shapes["panda_hand_tcp"] == [] and shapes["panda_link8"] == []
