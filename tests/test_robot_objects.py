"""The robot handles the person's object: open vessels held by their rim (no substitute), small
flat objects picked up, a put onto released on the static box's top (issue 62, item 3)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from robot_support import require_robot

from warpskill.contract.reconstruction import Reconstruction
from warpskill.geometry import cuboid_corners
from warpskill.nouns.typical import is_open_topped
from warpskill.synthetic import make_demonstration

robot = require_robot("placo", "mujoco")

LIFT = 0.05  # [m] a picked-up or carried object rises at least this much in the replay


def relations_truth(action: str, seed: int) -> Reconstruction:
    """The relations scenario's ground truth of ``action`` / ``seed``, with its object's noun."""
    demo = make_demonstration(action, seed=seed, input="boxes", scenarios="relations")
    return dataclasses.replace(Reconstruction(**demo.truth), object_noun=np.array(demo.object_noun))


def test_open_vessels_by_their_noun():
    assert all(is_open_topped(noun) for noun in ("cup", "coffee mugs", "tecup", "a bowl of soup", "glass"))
    assert not any(is_open_topped(noun) for noun in ("jar", "plate", "phone", "yellow clay container", "", None))


def test_a_reconstruction_without_a_noun_is_written_and_read_as_before(tmp_path):
    recon = relations_truth("pick_up", 1)
    unnamed = dataclasses.replace(recon, object_noun=np.array(""))
    unnamed.save(tmp_path / "old.npz")
    recon.save(tmp_path / "named.npz")
    with np.load(tmp_path / "old.npz") as old, np.load(tmp_path / "named.npz") as named:
        assert "object_noun" not in old.files and str(named["object_noun"]) == "card"
    assert str(Reconstruction.load(tmp_path / "old.npz").object_noun) == ""
    assert str(Reconstruction.load(tmp_path / "named.npz").object_noun) == "card"


def test_a_cup_wider_than_the_gripper_is_planned_by_its_rim_and_a_box_is_substituted():
    from warpskill.robot.sizes import USABLE_OPENING, fit_sizes

    recon = relations_truth("put_onto", 15)  # a 8.6 x 8.4 x 10.4 cm cup onto a book
    fitted, note = fit_sizes(recon)
    assert np.allclose(fitted.object_size, recon.object_size) and "by its rim" in note and "substitute" not in note
    boxed, note = fit_sizes(dataclasses.replace(recon, object_noun=np.array("box")))
    assert np.max(boxed.object_size[:2]) < USABLE_OPENING
    assert "substitute" in note and "no open vessel" in note


@pytest.mark.slow
def test_a_cup_is_held_by_its_rim_and_lifted_onto_the_book_in_mujoco():
    recon = relations_truth("put_onto", 15)
    plan = robot.retarget(recon)
    assert plan.grasp_name.startswith("rim_") and plan.object_noun == "cup"
    assert np.allclose(plan.object_size, recon.object_size), "the plan keeps the person's cup"
    assert "substitute" not in plan.note
    result = robot.replay(plan, recon, engine="mujoco")
    z = result.reconstruction.object_pos[:, 2]
    assert z.max() > z[0] + LIFT and result.evaluation.success, result.evaluation.checks


@pytest.mark.slow
def test_a_mug_skill_at_a_new_layout_is_held_by_its_rim_and_lifted_in_mujoco(capsys):
    from warpskill.bench.generalize import bench_generalize
    from warpskill.export.layouts import sample_layouts
    from warpskill.robot.sizes import fit_sizes
    from warpskill.robot.skill_layout import apply_skill, skill_from

    recon = relations_truth("put_onto", 5)  # a 12.6 x 9.1 x 9.9 cm mug onto a box
    skill = skill_from(recon)
    assert skill.object_noun == "mug"
    unnamed = dataclasses.replace(skill, object_noun="")  # a skill that does not know its object ...
    assert "substitute" in fit_sizes(apply_skill(unnamed, sample_layouts(unnamed, 1)[0]))[1]  # ... is substituted
    run = bench_generalize({"mug": recon}, layouts=1, engines=("mujoco",), robust=False)
    [outcome] = run.outcomes
    assert outcome.planned, outcome.reason
    plan = outcome.plan
    assert plan.layout is not None and plan.grasp_name.startswith("rim_") and plan.object_noun == "mug"
    assert np.allclose(plan.object_size, recon.object_size) and "substitute" not in plan.note
    replayed = outcome.replays["mujoco"]
    z = replayed.reconstruction.object_pos[:, 2]
    assert z.max() > z[0] + LIFT and replayed.success, replayed.evaluation.checks
    assert run.handled == {"mug": {"held by its rim": 1}}
    assert "objects: substituted in 0 plan(s), held by the rim in 1" in capsys.readouterr().out


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 3, 20])  # a card, a key, a phone: 1 cm tall
def test_a_flat_object_is_picked_up_in_mujoco(seed):
    recon = relations_truth("pick_up", seed)
    assert recon.object_size.min() < 0.011
    plan = robot.retarget(recon)
    result = robot.replay(plan, recon, engine="mujoco")
    z = result.reconstruction.object_pos[:, 2]
    assert z[-1] > z[0] + LIFT and result.evaluation.success, result.evaluation.checks


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 15])  # a candle (top grasp), a cup (rim grasp)
def test_a_put_onto_releases_on_the_static_top(seed):
    recon = relations_truth("put_onto", seed)
    plan = robot.retarget(recon)
    scene = plan.scene(recon)
    at = int(np.searchsorted(plan.t, plan.release_time))
    held = plan.tcp[at] @ np.linalg.inv(plan.grasp_pose)  # the object's planned pose as the gripper opens
    top = cuboid_corners(scene.static_pos[0], scene.static_rot[0], scene.static_size[0])[:, 2].max()
    half = 0.5 * float(np.abs(held[2, :3]) @ scene.object_size)
    assert abs(held[2, 3] - (top + half)) < 0.008
    assert robot.replay(plan, recon, engine="mujoco").evaluation.checks["released_on_top"]
