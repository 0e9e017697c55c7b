"""The package data (``assets/``): the robot scene both replays read, and the example annotation set."""

from __future__ import annotations

import dataclasses
import types

import numpy as np
import pytest

from warpskill import assets
from warpskill.data.boxes.something_else import read_something_else, something_else_demonstration
from warpskill.robot.scene_config import (
    RobotSceneConfig,
    SceneConfigError,
    load_scene_config,
    read_scene_config,
)

EXAMPLE = ("examples/annotations.json", "examples/phases.csv", "examples/actions.csv")


def test_assets_path_finds_the_installed_files():
    for name in ("robot_scene.toml", "examples/README.md", *EXAMPLE):
        assert assets.path(name).is_file(), name
    with pytest.raises(FileNotFoundError, match="no asset"):
        assets.path("missing.toml")


def test_scene_config_loads_once_with_todays_values():
    config = load_scene_config()
    assert isinstance(config, RobotSceneConfig) and load_scene_config() is config
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.object.mass = 1.0  # type: ignore[misc]
    assert config.mujoco.timestep == config.newton.timestep == 0.002
    assert config.object.mass == 0.2 and config.contact.friction == 1.0 and config.panda.grip_force == 40.0
    np.testing.assert_array_equal(config.panda.arm_kv, 0.1 * np.array(config.panda.arm_kp))
    assert config.panda.arm_torque_limit == (87.0,) * 4 + (12.0,) * 3
    assert config.video.lights and config.video.camera.distance > 0


def test_scene_config_rejects_missing_and_unknown_keys(tmp_path):
    text = assets.path("robot_scene.toml").read_text()
    bad = tmp_path / "scene.toml"
    bad.write_text(text.replace("mass = 0.2", "weight = 0.2"))
    with pytest.raises(SceneConfigError, match=r"object: missing mass; unknown weight"):
        read_scene_config(bad)
    bad.write_text(text.replace("iterations = 12", "iterations = 12.5"))
    with pytest.raises(SceneConfigError, match=r"newton.iterations: expected int"):
        read_scene_config(bad)
    bad.write_text(text.replace("object_contact_timeconst = 0.004", "object_contact_timeconst = 0.003"))
    with pytest.raises(SceneConfigError, match=r"object_contact_timeconst \(0.003 s\) must be at least twice"):
        read_scene_config(bad)


def test_example_annotations_make_a_demonstration():
    table = read_something_else(*(assets.path(name) for name in EXAMPLE))
    assert len(table) == 1
    (video,) = table.values()
    demo, notes = something_else_demonstration(video)
    assert video.action == demo.action == "put_next_to" and notes == []
    assert demo.hand_mask.shape[1:] == (240, 427) and demo.static_mask.shape[0] == 1
    assert demo.object_mask.any(axis=(1, 2)).all() and 0 < demo.contact.sum() < len(demo.contact)


# --------------------------------------------------------------------------- both replays read it

def _scene():
    """A standing plan (only what the model builders read: base, first joints, opening, scene) and its scene."""
    pytest.importorskip("mujoco")
    from warpskill.contract.reconstruction import Reconstruction
    from warpskill.robot.model import HOME_Q, RobotModelError, make_scene, panda_description_dir
    from warpskill.synthetic import make_demonstration

    try:
        panda_description_dir()
    except RobotModelError as error:  # pragma: no cover - depends on the environment
        pytest.skip(str(error))
    recon = Reconstruction(**make_demonstration("pick_up", seed=0, noise="none").truth)
    plan = types.SimpleNamespace(base=make_scene(recon).base, q=HOME_Q[None], gripper=np.array([0.08]),
                                 scene=lambda recon: recon)
    return plan, recon


@pytest.mark.slow
def test_mujoco_model_uses_the_scene_config():
    import mujoco

    from warpskill.robot import replay_mujoco

    config = load_scene_config()
    plan, recon = _scene()
    model = replay_mujoco.build_model(plan, recon)
    assert model.opt.timestep == config.mujoco.timestep
    assert model.opt.impratio == config.mujoco.impratio
    assert model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    np.testing.assert_array_equal(model.actuator_gainprm[:7, 0], config.panda.arm_kp)
    np.testing.assert_array_equal(-model.actuator_biasprm[:7, 2], config.panda.arm_kv)
    np.testing.assert_array_equal(model.actuator_forcerange[:7, 1], config.panda.arm_torque_limit)
    np.testing.assert_array_equal(model.actuator_gainprm[7:9, 0], config.panda.finger_kp)
    np.testing.assert_array_equal(model.actuator_forcerange[7:9, 1], config.panda.grip_force)
    assert model.body_mass[model.body("object").id] == pytest.approx(config.object.mass)
    assert model.geom_friction[model.geom("object").id, 0] == config.contact.friction
    np.testing.assert_allclose(model.geom_size[model.geom("table").id] * 2, config.table.size)
    assert model.nlight == len(config.video.lights)
    assert model.vis.global_.offwidth >= config.video.width


@pytest.mark.slow
def test_newton_model_uses_the_scene_config():
    pytest.importorskip("newton")
    pytest.importorskip("trimesh")
    from warpskill.robot import replay_newton

    config = load_scene_config()
    plan, recon = _scene()
    model, info = replay_newton.build_model(plan, recon, device="cpu")
    assert float(model.body_mass.numpy()[info["object_body"]]) == pytest.approx(config.object.mass, rel=1e-5)
    mu = model.shape_material_mu.numpy()[list(info["object_shapes"])]
    assert mu == pytest.approx(config.contact.friction)
    ke, kd = model.joint_target_ke.numpy(), model.joint_target_kd.numpy()
    effort = model.joint_effort_limit.numpy()
    driven = np.flatnonzero(ke > 0)
    panda = config.panda
    np.testing.assert_allclose(ke[driven], [*panda.arm_kp, panda.finger_kp, panda.finger_kp])
    np.testing.assert_allclose(kd[driven], [*panda.arm_kv, panda.finger_kv, panda.finger_kv], rtol=1e-6)
    np.testing.assert_allclose(effort[driven], [*panda.arm_torque_limit, panda.grip_force, panda.grip_force])
