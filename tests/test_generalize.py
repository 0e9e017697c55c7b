"""Random layouts over the reachable table, the perturbed replay, and a small generalisation run."""

from __future__ import annotations

import dataclasses
import logging
import math
from collections import Counter

import numpy as np
import pytest

from warpskill.contract.reconstruction import Reconstruction
from warpskill.export.layouts import BASE_CLEARANCE, HALF_ANGLE, INNER, OUTER, ReachableTable, sample_layouts
from warpskill.robot.placement import check_reach
from warpskill.robot.skill_layout import apply_skill, overlap_depth, skill_from
from warpskill.synthetic import make_demonstration


def truth(action: str) -> Reconstruction:
    return Reconstruction(**make_demonstration(action, seed=0, noise="none").truth)


@pytest.fixture(scope="module")
def put_skill():
    return skill_from(truth("put_next_to"))


def test_layouts_lie_in_reach_apart_and_are_seeded(put_skill):
    table = ReachableTable.of(put_skill)
    drawn = sample_layouts(put_skill, 12, seed=4, table=table)
    assert drawn == sample_layouts(put_skill, 12, seed=4, table=table)
    assert drawn != sample_layouts(put_skill, 12, seed=5, table=table)
    for layout in drawn:
        recon = apply_skill(put_skill, layout)
        radius, bearing = table.polar(recon.object_pos[:1, :2])  # the start on the sector ...
        assert np.all((radius >= INNER) & (radius <= OUTER) & (np.abs(bearing) <= HALF_ANGLE))
        assert table.contains(np.array(layout.statics)[:, :2]).all()
        check_reach(recon)  # ... and the whole held path keeps the reach margin (raises otherwise)
        assert overlap_depth(recon.object_pos[0], recon.object_rot[0], recon.object_size,
                             recon.static_pos[0], recon.static_rot[0], recon.static_size[0]) == 0.0
    yaws = np.array([layout.object[2] for layout in drawn])
    assert np.all(np.abs(yaws) <= math.pi) and np.ptp(yaws) > math.pi  # any yaw, not one


def test_a_long_objects_layouts_keep_it_out_of_the_robots_base():
    # A 60 cm object centred on the sector (at least 35 cm from the base's axis) could reach
    # into the robot's base column; no drawn layout lets it.
    long = dataclasses.replace(truth("push_left_to_right"), object_size=np.array([0.6, 0.08, 0.05]))
    skill = skill_from(long)
    table = ReachableTable.of(skill)
    base = table.base[:2, 3]
    for layout in sample_layouts(skill, 30, seed=0, table=table):
        recon = apply_skill(skill, layout)
        grid = np.stack(np.meshgrid(*[np.linspace(-0.5, 0.5, 25)] * 3), -1).reshape(-1, 3)  # through the box
        points = recon.object_pos[0] + (grid * recon.object_size) @ recon.object_rot[0].T
        assert np.linalg.norm(points[:, :2] - base, axis=1).min() >= BASE_CLEARANCE - 1e-3
    # a box across the base's axis, its corners far from it, is not clear
    assert not table.clear_of_base(np.array([*base, 0.05]), np.eye(3), long.object_size)
    assert table.clear_of_base(np.array([*base, 0.05]) + [0.0, 0.3, 0.0], np.eye(3), long.object_size)


def test_table_samples_cover_the_sector_uniformly():
    table = ReachableTable(base=np.eye(4))
    rng = np.random.default_rng(0)
    points = np.array([table.sample(rng) for _ in range(4000)])
    radius, bearing = table.polar(points)
    assert table.contains(points).all()
    # uniform over the area: the fraction within radius r grows as (r^2 - inner^2) / (outer^2 - inner^2)
    middle = math.sqrt(0.5 * (INNER**2 + OUTER**2))
    assert abs(np.mean(radius < middle) - 0.5) < 0.03 and abs(np.mean(bearing > 0) - 0.5) < 0.03


def test_perturbation_changes_the_simulated_mass_friction_and_start():
    pytest.importorskip("mujoco")
    from robot_support import require_robot

    require_robot("placo", "mujoco")
    from warpskill.robot import replay_mujoco, retarget
    from warpskill.robot.perturbation import Perturbation

    recon = truth("pick_up")
    plan = retarget(recon)
    model = replay_mujoco.build_model(plan, recon)
    body = model.body("object").id
    mass, friction, inertia = model.body_mass[body], model.geom_friction[:, 0].copy(), model.body_inertia[body].copy()
    Perturbation("p", mass_scale=2.0, friction_scale=0.7)(model)
    assert model.body_mass[body] == pytest.approx(2.0 * mass)
    np.testing.assert_allclose(model.body_inertia[body], 2.0 * inertia)
    np.testing.assert_allclose(model.geom_friction[:, 0], 0.7 * friction)
    # the object starts where the perturbation put it: 1 cm along x, turned 5 deg about z
    times = np.array([0.0])
    moved = Perturbation("off", shift=(0.01, 0.0), turn=math.radians(5.0))
    plain = replay_mujoco.simulate(plan, recon, times)
    off = replay_mujoco.simulate(plan, recon, times, edit_model=moved)
    np.testing.assert_allclose(off["object_pos"][0] - plain["object_pos"][0], [0.01, 0.0, 0.0], atol=1e-6)
    turn = off["object_rot"][0] @ plain["object_rot"][0].T
    assert math.degrees(math.atan2(turn[1, 0], turn[0, 0])) == pytest.approx(5.0, abs=1e-4)


@pytest.mark.slow
def test_generalize_two_layouts(capsys, tmp_path):
    from robot_support import require_robot

    require_robot("placo", "mujoco")
    from warpskill.bench.generalize import bench_generalize
    from warpskill.bench.outcomes import load_outcomes

    result = bench_generalize({"pick_up": truth("pick_up")}, layouts=2, seed=1, out=tmp_path)
    rows = result.rows
    assert set(rows) == {"planned", "replay mujoco", "robust"}
    assert all(len(results) == 2 and {a for a, _ in results} == {"pick_up"} for results in rows.values())
    for k in range(2):  # robust only where it succeeded, succeeded only where it was planned
        assert rows["robust"][k][1] <= rows["replay mujoco"][k][1] <= rows["planned"][k][1]
    misses = sum(not ok for results in rows.values() for _, ok in results)
    assert (misses == 0) == (not result.misses)
    out = capsys.readouterr().out
    assert "| planned" in out and "| robust" in out
    redrawn = result.redrawn["pick_up"]  # the draws refused before planning, by reason, shown
    assert f"layouts redrawn before planning: {redrawn.total()}" in out
    table = load_outcomes(tmp_path)  # one row per layout, its robot verdicts as in the table above
    assert list(table) == ["pick_up/layout 0", "pick_up/layout 1"]
    for k, case in enumerate(table.values()):
        assert case.success == rows["replay mujoco"][k][1]
        assert case.robot_success == rows["robust"][k][1]
        assert list(case.robot.misses) == result.outcomes[k].misses()


def test_a_skill_no_layout_fits_counts_as_unplanned_and_says_why(caplog, capsys):
    caplog.set_level(logging.INFO, logger="warpskill")
    pytest.importorskip("mujoco")
    from warpskill.bench.generalize import bench_generalize

    recon = truth("put_behind")
    # A static box 2 m across: it covers the object wherever a layout puts them, so every
    # layout is refused, and the benchmark counts the skill's layouts as misses.
    recon.static_size[0, :2] = 2.0
    result = bench_generalize({"into-the-box": recon}, layouts=2, engines=("mujoco",), robust=False)
    assert result.rows["planned"] == [("put_behind", False)] * 2
    assert result.rows["replay mujoco"] == [("put_behind", False)] * 2
    [miss] = result.misses
    assert miss.startswith("into-the-box: every layout: ")
    assert any(line.startswith("into-the-box: no layout: ") for line in caplog.messages)
    assert [(c.case, c.failed_checks, c.robot_success) for c in result.cases] == \
        [("into-the-box/layout 0", ("plan",), False), ("into-the-box/layout 1", ("plan",), False)]
    # refused at its own layout already (the box covers the object's start): nothing drawn, nothing redrawn
    assert result.redrawn == {"into-the-box": Counter()}
    assert "layouts redrawn before planning: 0\n" in capsys.readouterr().out


def test_generalize_refuses_the_robust_row_without_mujoco():
    from warpskill.bench.generalize import bench_generalize

    with pytest.raises(ValueError, match="robust replays need the mujoco engine"):
        bench_generalize({"pick_up": truth("pick_up")}, layouts=1, engines=("newton",))
