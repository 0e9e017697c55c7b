"""Video to robot: the end-to-end benchmark's robot columns (``bench something-else --robot``, ``bench robot``)."""

from __future__ import annotations

import numpy as np
import pytest
from robot_support import require_robot

robot = require_robot("placo", "mujoco")
from warpskill import assets  # noqa: E402
from warpskill.bench.outcomes import load_outcomes  # noqa: E402
from warpskill.cli import main  # noqa: E402
from warpskill.contract.reconstruction import Reconstruction  # noqa: E402
from warpskill.synthetic import make_demonstration  # noqa: E402

# Every test here reconstructs, plans and replays (seconds each).
pytestmark = pytest.mark.slow


EXAMPLE = ("examples/annotations.json", "examples/phases.csv", "examples/actions.csv")
VIDEO = "synthetic-put_next_to-0"  # the example annotation set's one video


def truth(action: str, seed: int) -> Reconstruction:
    return Reconstruction(**make_demonstration(action, seed=seed, noise="none").truth)


def _table_rows(printed: str) -> dict[str, str]:
    return {line.split("|")[1].strip(): line for line in printed.splitlines() if line.startswith("| ")}


def test_bench_something_else_robot_columns(tmp_path, capsys):
    # The bench reuses a reconstruction found in OUT/<video>/: here the example video's ground truth.
    (tmp_path / VIDEO).mkdir()
    truth("put_next_to", 0).save(tmp_path / VIDEO / "reconstruction.npz")
    files = [str(assets.path(name)) for name in EXAMPLE]
    assert main(["bench", "something-else", "--annotations", files[0], "--phases", files[1], "--actions", files[2],
                 "-o", str(tmp_path), "--robot", "--engines", "mujoco", "--video"]) == 0
    printed = capsys.readouterr().out
    rows = _table_rows(printed)
    for row in ("full method (box masks)", "planned", "replay mujoco", "end to end"):
        assert "1/1" in rows[row], printed
    assert "replay newton" not in rows
    # The per-video table: reconstruction, plan, one column per engine.
    assert f"| {VIDEO} | put_next_to | ok | found | ok |" in printed
    assert "end to end (reconstruction and every replay meet the criteria): 1/1 (100.0 %)" in printed
    assert "done before" in printed
    for name in ("plan.npz", "replay_mujoco.npz"):
        assert (tmp_path / VIDEO / name).is_file(), name
    assert robot.Replay.load(tmp_path / VIDEO / "replay_mujoco.npz").success
    assert (tmp_path / VIDEO / "replay.mp4").is_file() or (tmp_path / VIDEO / "replay.png").is_file()
    [case] = load_outcomes(tmp_path).values()  # the robot's verdict is in the outcome table
    assert case.robot_success and case.robot.replays == {"mujoco": True} and case.robot.misses == ()


def test_bench_something_else_robot_reports_a_missing_plan_in_one_line(tmp_path, capsys, monkeypatch):
    from warpskill.bench import end_to_end
    from warpskill.bench.end_to_end import RobotOutcome, robot_rows
    from warpskill.bench.something_else import bench_something_else

    def no_plan(recon, **kwargs):
        raise robot.PlanError("frame 15: no feasible grasp:\n  the cuboid is out of reach")

    monkeypatch.setattr(end_to_end, "retarget", no_plan)  # the planner the benchmark calls
    (tmp_path / VIDEO).mkdir()
    truth("put_next_to", 0).save(tmp_path / VIDEO / "reconstruction.npz")
    result = bench_something_else(*(assets.path(name) for name in EXAMPLE), out=tmp_path, robot=True,
                                  engines=("mujoco", "newton"), pictures=False)
    printed = capsys.readouterr().out
    outcome = result.robot[VIDEO]
    assert not outcome.planned and outcome.reason == "frame 15: no feasible grasp: the cuboid is out of reach"
    assert f"| {VIDEO} | put_next_to | ok | none: {outcome.reason} | - | - |" in printed
    assert result.rows["full method (box masks)"] == [("put_next_to", True)]
    assert result.rows["planned"] == result.rows["end to end"] == [("put_next_to", False)]
    assert result.agreement["cases"] == 0
    [case] = result.outcomes
    assert case.success and case.robot_success is False and case.robot.misses == (f"plan: {outcome.reason}",)

    # A video without a reconstruction fails every robot row.
    rows = robot_rows([("pick_up", True, RobotOutcome(reason="x")), ("pick_up", False, None)], ("mujoco", "newton"))
    assert rows["planned"] == rows["replay newton"] == rows["end to end"] == [("pick_up", False)] * 2
    assert rows["reconstruction"] == [("pick_up", True), ("pick_up", False)]


def test_robot_step_agrees_across_engines_and_keeps_the_files(tmp_path):
    pytest.importorskip("newton")
    pytest.importorskip("trimesh")
    from warpskill.bench.end_to_end import agreement, robot_step

    outcome = robot_step(truth("push_left_to_right", 2), tmp_path, engines=("mujoco", "newton"))
    assert outcome.planned and outcome.replayed and outcome.agree()
    assert outcome.end_difference() < 0.03
    assert set(outcome.cpu_seconds) == {"mujoco", "newton"}
    for name in ("plan.npz", "replay_mujoco.npz", "replay_newton.npz"):
        assert (tmp_path / name).is_file(), name
    newton = robot.Replay.load(tmp_path / "replay_newton.npz")
    assert newton.engine == "newton" and newton.success
    np.testing.assert_allclose(newton.reconstruction.object_pos, outcome.replays["newton"].reconstruction.object_pos)
    summary = agreement([outcome, None])
    assert summary["cases"] == 1 and summary["agree"] == 1 and summary["disagree"] == []


def test_robot_step_replays_a_successful_plan_under_every_perturbation():
    pytest.importorskip("mujoco")
    from warpskill.bench.end_to_end import robot_rows, robot_step
    from warpskill.robot.perturbation import PERTURBATIONS

    outcome = robot_step(truth("push_left_to_right", 2), engines=("mujoco",), robust=True)
    assert outcome.replayed
    assert list(outcome.perturbed) == [p.name for p in PERTURBATIONS]
    assert outcome.robust == all(outcome.perturbed.values())
    assert outcome.broken_by() == [name for name, ok in outcome.perturbed.items() if not ok]
    broken = outcome.broken_by()
    assert outcome.misses() == ([f"not robust: fails under {', '.join(broken)}"] if broken else [])
    rows = robot_rows([("push_left_to_right", True, outcome)], ("mujoco",), robust=True)
    assert rows["robust"] == [("push_left_to_right", outcome.robust)]
    assert "robust" not in robot_rows([("push_left_to_right", True, outcome)], ("mujoco",))


def test_robust_replays_need_mujoco():
    from warpskill.bench.end_to_end import robot_step

    with pytest.raises(ValueError, match="robust replays need the mujoco engine"):
        robot_step(truth("push_left_to_right", 2), engines=("newton",), robust=True)
