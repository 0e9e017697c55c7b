"""Replaying Panda plans in Newton (issue 5): it agrees with MuJoCo on success (CPU, kept short)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("placo")
pytest.importorskip("mujoco")
pytest.importorskip("newton")
pytest.importorskip("trimesh")  # Newton's URDF importer reads the collision meshes with it
from warpskill.reconstruction import Reconstruction  # noqa: E402
from warpskill.synthetic import make_demonstration  # noqa: E402

robot = pytest.importorskip("warpskill.robot")
from warpskill.robot.model import RobotModelError, panda_description_dir  # noqa: E402

try:
    panda_description_dir()
except RobotModelError as error:  # pragma: no cover - depends on the environment
    pytest.skip(str(error), allow_module_level=True)


def test_newton_agrees_with_mujoco_on_a_pick_up():
    recon = Reconstruction(**make_demonstration("pick_up", seed=0, noise="none").truth)
    plan = robot.retarget(recon)
    mujoco = robot.replay(plan, recon, engine="mujoco")
    newton = robot.replay(plan, recon, engine="newton", device="cpu")
    assert newton.engine == "newton"
    assert newton.success == mujoco.success, (mujoco.evaluation.checks, newton.evaluation.checks)
    assert newton.success
    replayed = newton.reconstruction
    assert replayed.num_frames == mujoco.reconstruction.num_frames
    assert np.isfinite(replayed.object_pos).all()
    # Both engines carry the cuboid along the same path (the robot tracks the same plan).
    assert np.abs(replayed.object_pos - mujoco.reconstruction.object_pos).max() < 0.03
    # The gripper holds it in Newton too, for about as long.
    held, held_mujoco = replayed.grasped > 0.5, mujoco.reconstruction.grasped > 0.5
    assert abs(int(held.sum()) - int(held_mujoco.sum())) <= 0.2 * held_mujoco.sum()
