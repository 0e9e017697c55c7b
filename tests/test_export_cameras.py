"""The dataset cameras' calibration against MuJoCo's own free camera, and the tool pose's quaternions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from warpskill.export.rollouts import CAMERAS, FOVY, pose_vectors


@pytest.mark.parametrize("name", sorted(CAMERAS))
def test_calibration_is_mujocos_free_camera(name):
    mujoco = pytest.importorskip("mujoco")
    model = mujoco.MjModel.from_xml_string("<mujoco/>")
    model.vis.global_.fovy = FOVY
    data, scene = mujoco.MjData(model), mujoco.MjvScene(model, maxgeom=10)
    yaw = 0.7
    base = np.eye(4)
    base[:3, :3] = [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]]
    base[:3, 3] = [0.3, -0.2, 0.0]
    camera = CAMERAS[name]
    mujoco.mjv_updateScene(model, data, mujoco.MjvOption(), None, camera.view(base), mujoco.mjtCatBit.mjCAT_ALL,
                           scene)
    gl = mujoco.mjv_averageCamera(scene.camera[0], scene.camera[1])  # the eyes' mean: what mono rendering uses
    calibration = camera.calibration(width=64, height=48)
    world = base @ calibration.base_from_camera
    np.testing.assert_allclose(world[:3, 3], gl.pos, atol=1e-5)
    np.testing.assert_allclose(world[:3, 2], gl.forward, atol=1e-5)  # OpenCV z: along the view
    np.testing.assert_allclose(-world[:3, 1], gl.up, atol=1e-5)  # OpenCV y: down the image
    focal = 0.5 * 48 * gl.frustum_near / gl.frustum_top  # [px] the GL frustum's vertical focal length
    assert calibration.fy == pytest.approx(focal, rel=1e-5) and calibration.fx == calibration.fy
    assert (calibration.cx, calibration.cy) == (31.5, 23.5)


def test_pose_vectors_are_continuous_unit_quaternions():
    pytest.importorskip("mujoco")
    angles = np.linspace(0.0, 3.0 * math.pi, 40)  # past a full turn: a naive conversion flips sign
    poses = np.tile(np.eye(4), (len(angles), 1, 1))
    poses[:, 0, 0] = poses[:, 1, 1] = np.cos(angles)
    poses[:, 1, 0], poses[:, 0, 1] = np.sin(angles), -np.sin(angles)
    poses[:, :3, 3] = np.column_stack([angles, 2 * angles, 3 * angles])
    vectors = pose_vectors(poses)
    np.testing.assert_allclose(vectors[:, :3], poses[:, :3, 3])
    np.testing.assert_allclose(np.abs(vectors[:, 3]), np.abs(np.cos(angles / 2)), atol=1e-9)  # w first
    np.testing.assert_allclose(np.abs(vectors[:, 6]), np.abs(np.sin(angles / 2)), atol=1e-9)  # z last
    assert vectors[0, 3] >= 0 and np.all(np.sum(vectors[1:, 3:] * vectors[:-1, 3:], axis=1) > 0)
