"""``warpskill export mjcf``: the robot's scene as one MJCF file that loads in a user's own MuJoCo."""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest
from robot_support import require_robot

robot = require_robot("mujoco")
import mujoco  # noqa: E402

from warpskill.cli import main  # noqa: E402
from warpskill.contract import Reconstruction  # noqa: E402
from warpskill.robot import Placement  # noqa: E402
from warpskill.robot.model import make_scene  # noqa: E402
from warpskill.robot.skill_layout import apply_skill, demonstrated_layout, skill_from  # noqa: E402
from warpskill.synthetic import make_demonstration  # noqa: E402

DIGITS = 1e-5  # [m] MjSpec.to_xml writes 6 significant digits


@functools.cache
def truth(action: str, seed: int = 0) -> Reconstruction:
    """The ground truth of a synthetic demonstration (made once per test run; never modified)."""
    return Reconstruction(**make_demonstration(action, seed=seed, noise="none").truth)


def load(path, monkeypatch, folder):
    """The model and its data after forward kinematics, loaded from another working folder."""
    monkeypatch.chdir(folder)
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def assert_scene(model, data, scene: Reconstruction, base: np.ndarray) -> None:
    """The bodies and boxes stand where ``scene`` and ``base`` put them."""
    np.testing.assert_allclose(data.xpos[model.body("object").id], scene.object_pos[0], atol=DIGITS)
    np.testing.assert_allclose(data.xmat[model.body("object").id].reshape(3, 3), scene.object_rot[0], atol=DIGITS)
    np.testing.assert_allclose(data.xpos[model.body("panda_link0").id], base[:3, 3], atol=DIGITS)
    np.testing.assert_allclose(data.xmat[model.body("panda_link0").id].reshape(3, 3), base[:3, :3], atol=DIGITS)
    for k in range(scene.num_static):
        geom = model.geom(f"static{k}").id
        np.testing.assert_allclose(data.geom_xpos[geom], scene.static_pos[k], atol=DIGITS)
        np.testing.assert_allclose(data.geom_xmat[geom].reshape(3, 3), scene.static_rot[k], atol=DIGITS)
        np.testing.assert_allclose(2 * model.geom_size[geom], scene.static_size[k], atol=DIGITS)


def test_export_a_layout_at_a_fixed_base(tmp_path, monkeypatch):
    recon = truth("put_behind")
    recon.save(tmp_path / "recon.npz")
    layout = demonstrated_layout(skill_from(recon))
    x, y = layout.object[0] + 0.05, layout.object[1] - 0.03
    sx, sy = layout.statics[0][0] - 0.04, layout.statics[0][1] + 0.02
    assert main(["export", "mjcf", str(tmp_path / "out" / "scene.xml"), str(tmp_path / "recon.npz"),
                 "--object-at", str(x), str(y), "20", "--static-at", str(sx), str(sy), "45",
                 "--offset", "0.5", "0.0", "--yaw", "90"]) == 0
    assert (tmp_path / "out" / "scene_meshes" / "link0.stl").is_file()
    model, data = load(tmp_path / "out" / "scene.xml", monkeypatch, tmp_path)
    moved = dataclasses.replace(layout, object=(x, y, math.radians(20)), statics=((sx, sy, math.radians(45)),))
    scene = apply_skill(skill_from(recon), moved)
    assert_scene(model, data, scene, make_scene(scene, Placement(offset=(0.5, 0.0), yaw=math.pi / 2)).base)
    np.testing.assert_allclose(data.xpos[model.body("object").id][:2], (x, y), atol=DIGITS)


def test_export_refuses_an_impossible_layout(tmp_path, capsys):
    truth("put_behind").save(tmp_path / "recon.npz")
    layout = demonstrated_layout(skill_from(truth("put_behind")))
    status = main(["export", "mjcf", str(tmp_path / "scene.xml"), str(tmp_path / "recon.npz"),
                   "--object-at", *map(str, layout.statics[0][:2]), "0", "--offset", "0.5", "0.0"])
    err = capsys.readouterr().err
    assert status == 2 and err.startswith("warpskill: error: layout refused: the object's start overlaps")
    assert not (tmp_path / "scene.xml").exists()


@pytest.mark.slow
def test_export_at_the_plans_base(tmp_path, monkeypatch):
    pytest.importorskip("placo")
    recon = truth("push_left_to_right")
    recon.save(tmp_path / "recon.npz")
    plan = robot.retarget(recon)
    plan.save(tmp_path / "plan.npz")
    assert main(["export", "mjcf", str(tmp_path / "scene.xml"), str(tmp_path / "recon.npz"),
                 "--plan", str(tmp_path / "plan.npz")]) == 0
    model, data = load(tmp_path / "scene.xml", monkeypatch, tmp_path / "..")
    assert_scene(model, data, plan.scene(recon), plan.base)
