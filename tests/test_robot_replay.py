"""Replaying Panda plans in MuJoCo: ground-truth reconstructions succeed; the CLI writes replay.npz."""

from __future__ import annotations

import numpy as np
import pytest
from robot_support import require_robot

robot = require_robot("placo", "mujoco")
from warpskill.cli import main  # noqa: E402
from warpskill.contract.reconstruction import FIELD_SHAPES, Reconstruction  # noqa: E402
from warpskill.synthetic import make_demonstration  # noqa: E402


def truth(action: str, seed: int) -> Reconstruction:
    return Reconstruction(**make_demonstration(action, seed=seed, noise="none").truth)


@pytest.mark.slow
@pytest.mark.parametrize(
    "action, seed",
    [("pick_up", 0), ("pull_left_to_right", 0), ("pull_right_to_left", 0), ("push_right_to_left", 1),
     ("put_in_front_of", 0), ("put_next_to", 0)],
)
def test_mujoco_replay_succeeds(action, seed):
    recon = truth(action, seed)
    plan = robot.retarget(recon)
    result = robot.replay(plan, recon, engine="mujoco")
    assert result.success, result.evaluation.checks
    replayed = result.reconstruction
    assert replayed.fps == recon.fps
    # The gripper's TCP stands for the hand tip: it reaches the object while holding it.
    held = replayed.grasped > 0.5
    if plan.grasp_kind == "grasp":
        assert held.any()
        gap = np.linalg.norm(replayed.hand_pos[held] - replayed.object_pos[held], axis=1)
        assert gap.max() < np.linalg.norm(recon.object_size)


@pytest.mark.slow
def test_a_thin_object_lying_flat_is_lifted_not_ridden_over():
    # A pen-like object 2 cm tall: the finger pads hold only its top centimetre. With MuJoCo's
    # default soft contacts the 40 N squeeze sinks a pad into it until the pad slides over its
    # top edge and the object stays on the table; the rigid contacts of robot_scene.toml keep
    # the pads beside it.
    recon = Reconstruction(**make_demonstration("pick_up", seed=0, noise="none", scenarios="flat", input="boxes").truth)
    assert recon.object_size.min() < 0.02 and recon.object_size.max() > 0.1
    plan = robot.retarget(recon)
    result = robot.replay(plan, recon, engine="mujoco")
    assert result.success, result.evaluation.checks


def test_an_edited_model_keeps_a_heavier_object_on_the_table():
    recon = truth("push_left_to_right", 0)
    plan = robot.retarget(recon)

    def heavier(model):  # the object twice as heavy, same density
        body = model.body("object").id
        model.body_mass[body] *= 2.0
        model.body_inertia[body] *= 2.0

    result = robot.replay(plan, recon, edit_model=heavier)
    assert result.success, result.evaluation.checks
    # The contacts are as stiff as for the built mass: the pushed object slides on the table, never through it.
    assert np.isfinite(result.reconstruction.object_pos).all()
    assert result.reconstruction.object_pos[:, 2].min() > 0.0


def test_cli_retarget_and_replay(tmp_path, capsys):
    recon = truth("pick_up", 0)
    recon.save(tmp_path / "recon.npz")
    assert main(["retarget", str(tmp_path / "recon.npz"), "-o", str(tmp_path / "plan.npz")]) == 0
    assert (tmp_path / "plan.csv").is_file()
    assert main(["replay", str(tmp_path / "plan.npz"), str(tmp_path / "recon.npz"), "-o", str(tmp_path / "out")]) == 0
    with np.load(tmp_path / "out" / "replay.npz") as out:
        assert set(FIELD_SHAPES) <= set(out.files)
        assert bool(out["success"])
    assert "pick_up: success" in capsys.readouterr().out


def test_cli_bad_plan_is_one_line(tmp_path, capsys):
    recon = truth("put_onto", 0)  # too wide to grasp: --keep-size refuses a substitute
    recon.save(tmp_path / "recon.npz")
    assert main(["retarget", str(tmp_path / "recon.npz"), "-o", str(tmp_path / "plan.npz"), "--keep-size"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("warpskill: error: frame 15") and "no feasible grasp" in err
    assert "wider than the gripper's 0.074 m usable opening" in err and err.count("\n") == 1


def test_unknown_engine():
    recon = truth("pick_up", 0)
    with pytest.raises(ValueError, match="unknown engine"):
        robot.replay(None, recon, engine="bullet")


def test_cli_placement_moves_the_robot(tmp_path, capsys):
    recon = truth("push_left_to_right", 0)
    recon.save(tmp_path / "recon.npz")
    assert main(["retarget", str(tmp_path / "recon.npz"), "-o", str(tmp_path / "a.npz")]) == 0
    assert "placement (auto): scene centre at" in capsys.readouterr().out
    assert main(["retarget", str(tmp_path / "recon.npz"), "-o", str(tmp_path / "b.npz"),
                 "--offset", "0.45", "0.05", "--yaw", "80"]) == 0
    assert "placement (given): scene centre at (0.45, 0.05) m in the base frame, yaw 80 deg" in capsys.readouterr().out
    a, b = robot.RobotPlan.load(tmp_path / "a.npz"), robot.RobotPlan.load(tmp_path / "b.npz")
    assert a.placement == "auto" and b.placement == "given"
    yaw = lambda base: np.degrees(np.arctan2(base[1, 0], base[0, 0]))  # noqa: E731
    assert yaw(a.base) == pytest.approx(np.degrees(a.yaw)) and yaw(b.base) == pytest.approx(80.0)
    # The same scene centre sits at each plan's offset in its base frame.
    centre_a = a.base[:2, 3] + a.base[:2, :2] @ a.offset
    centre_b = b.base[:2, 3] + b.base[:2, :2] @ np.array([0.45, 0.05])
    np.testing.assert_allclose(centre_a, centre_b, atol=1e-9)


@pytest.mark.slow
def test_cli_demo_runs_the_robot_steps(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out), "--action", "push_left_to_right", "--iterations", "5", "--quiet"]) == 0
    printed = capsys.readouterr().out
    for name in ("reconstruction.npz", "plan.npz", "plan.csv", "replay.npz"):
        assert (out / name).is_file(), printed
    assert (out / "replay.mp4").is_file() or (out / "replay.png").is_file()
    assert "replay: " in printed and printed.count("push_left_to_right: ") == 2


@pytest.mark.slow
def test_bench_robot_prints_the_table_and_keeps_the_plans(tmp_path, capsys):
    assert main(["bench", "robot", "--seeds", "1", "--actions", "push_left_to_right", "put_onto",
                 "-o", str(tmp_path), "--video"]) == 0
    printed = capsys.readouterr().out
    rows = {line.split("|")[1].strip(): line for line in printed.splitlines() if line.startswith("| ")}
    # push_left_to_right 0 plans and succeeds; put_onto 0's cuboid is too wide: a substitute is put onto the box.
    assert "2/2" in rows["planned"] and "2/2" in rows["replay mujoco"]
    assert "robust" in rows  # each success replayed again under the perturbations
    assert "put_onto" in printed and "substituted" in printed
    assert (tmp_path / "push_left_to_right_0" / "plan.npz").is_file()
    video = tmp_path / "push_left_to_right_0"
    assert (video / "replay.mp4").is_file() or (video / "replay.png").is_file()
    assert (tmp_path / "put_onto_0" / "plan.npz").is_file()
