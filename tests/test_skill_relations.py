"""The relation a skill keeps at a new layout: next to in the box's frame, behind / in front of from the
camera, onto its top; a layout where it cannot be met refused before planning and redrawn."""

from __future__ import annotations

import dataclasses
import functools
import math
from collections import Counter
from itertools import islice

import numpy as np
import pytest

from warpskill.contract import Layout, LayoutError, Reconstruction, evaluate
from warpskill.export.layouts import layouts
from warpskill.robot.skill_layout import VIEW, apply_skill, demonstrated_layout, skill_from
from warpskill.synthetic import make_demonstration


@functools.cache
def truth(action: str, seed: int = 0) -> Reconstruction:
    """The ground truth of a synthetic demonstration (made once per test run; never modified)."""
    return Reconstruction(**make_demonstration(action, seed=seed, noise="none").truth)


def release(recon: Reconstruction) -> int:
    """The release frame: the first after the last held one."""
    return int(np.flatnonzero(recon.grasped > 0.5)[-1]) + 1


def box_moved(layout: Layout, dx: float, dy: float, dyaw: float) -> Layout:
    """``layout`` with its static box shifted by (dx, dy) [m] and turned by dyaw [rad]; the object's start kept."""
    x, y, yaw = layout.statics[0]
    return dataclasses.replace(layout, statics=((x + dx, y + dy, yaw + dyaw),))


def in_box_frame(recon: Reconstruction, k: int) -> np.ndarray:
    """(3,) [m] the object's centre at frame ``k`` in the static box's frame."""
    return recon.static_rot[0].T @ (recon.object_pos[k] - recon.static_pos[0])


def gap_along(recon: Reconstruction, k: int, out: np.ndarray) -> float:
    """[m] the gap between the static box and the object at frame ``k`` along the world direction ``out``."""
    extents = [0.5 * float(np.abs(rot.T @ out) @ size) for rot, size in
               ((recon.static_rot[0], recon.static_size[0]), (recon.object_rot[k], recon.object_size))]
    return float((recon.object_pos[k] - recon.static_pos[0]) @ out) - sum(extents)


@pytest.mark.parametrize("dyaw", [math.radians(25), math.radians(-30), math.pi])
def test_next_to_keeps_its_side_and_gap_in_the_boxs_frame(dyaw):
    recon = truth("put_next_to")
    skill = skill_from(recon)
    k = release(recon)
    carried = apply_skill(skill, box_moved(demonstrated_layout(skill), 0.08, 0.06, dyaw))
    demo, new = in_box_frame(recon, k), in_box_frame(carried, k)
    side = int(np.argmax(np.abs(demo[:2])))
    assert np.sign(new[side]) == np.sign(demo[side])  # the same face of the box ...
    assert new[1 - side] == pytest.approx(demo[1 - side], abs=1e-9)  # ... at the same place along it ...
    out = [math.copysign(1.0, r[side]) * rec.static_rot[0][:, side] for r, rec in ((demo, recon), (new, carried))]
    assert gap_along(carried, k, out[1]) == pytest.approx(gap_along(recon, k, out[0]), abs=1e-9)  # ... and gap
    assert evaluate(carried).success, evaluate(carried).checks


@pytest.mark.parametrize("action", ["put_behind", "put_in_front_of"])
def test_behind_and_in_front_are_kept_as_the_camera_sees_them(action):
    recon = truth(action)
    skill = skill_from(recon)
    k = release(recon)
    carried = apply_skill(skill, box_moved(demonstrated_layout(skill), -0.1, 0.04, math.radians(70)))
    toward = VIEW if action == "put_behind" else -VIEW
    assert gap_along(carried, k, toward) == pytest.approx(gap_along(recon, k, toward), abs=1e-9)
    half_width = 0.5 * float(np.abs(carried.static_rot[0][0]) @ carried.static_size[0])  # the box's world x extent
    assert abs(carried.object_pos[k, 0] - carried.static_pos[0, 0]) <= half_width
    assert evaluate(carried).success, evaluate(carried).checks


def test_onto_keeps_its_place_on_the_turned_top():
    recon = truth("put_onto")
    k = release(recon)
    shifted = dataclasses.replace(recon, object_pos=recon.object_pos + (0.02, -0.015, 0.0))  # off the top's centre
    skill = skill_from(shifted)
    carried = apply_skill(skill, box_moved(demonstrated_layout(skill), 0.05, 0.0, math.radians(90)))
    np.testing.assert_allclose(in_box_frame(carried, k)[:2], in_box_frame(shifted, k)[:2], atol=1e-9)
    assert evaluate(carried).success, evaluate(carried).checks


def test_a_next_to_whose_side_faces_the_camera_is_refused_before_planning():
    skill = skill_from(truth("put_next_to"))
    turned = box_moved(demonstrated_layout(skill), 0.0, 0.0, math.radians(90))  # its side now behind the box
    with pytest.raises(LayoutError, match="layout refused: the put next to relation cannot be met: .*next_to_static"
                       ) as error:
        apply_skill(skill, turned)
    assert error.value.reason == "relation not met" and "\n" not in str(error.value)


def test_the_drawer_redraws_layouts_that_cannot_be_met_and_counts_why():
    skill = skill_from(truth("put_next_to"))
    redrawn: Counter[str] = Counter()
    drawn = list(islice(layouts(skill, seed=2, redrawn=redrawn), 6))
    assert all(evaluate(apply_skill(skill, layout)).success for layout in drawn)
    assert redrawn["relation not met"] > 0  # a next-to side turned to face the camera, or away from it
    again: Counter[str] = Counter()
    assert list(islice(layouts(skill, seed=2, redrawn=again), 6)) == drawn and again == redrawn  # seeded, counts too


@pytest.mark.slow
def test_a_next_to_at_a_turned_box_replays_in_mujoco():
    from robot_support import require_robot

    robot = require_robot("placo", "mujoco")
    recon = truth("put_next_to")
    skill = skill_from(recon)
    layout = box_moved(demonstrated_layout(skill), 0.08, 0.06, math.radians(25))
    plan = robot.retarget(skill, layout=layout)
    result = robot.replay(plan, recon, engine="mujoco")
    assert result.success, result.evaluation.checks
    replayed, k = result.reconstruction, release(recon)
    demo = in_box_frame(recon, k)
    side = int(np.argmax(np.abs(demo[:2])))
    assert np.sign(in_box_frame(replayed, -1)[side]) == np.sign(demo[side])  # it came to rest on that side


def test_a_put_held_to_the_videos_end_meets_its_relation_there():
    recon = truth("put_next_to")
    k = release(recon)
    held = dataclasses.replace(recon, grasped=np.where(np.arange(recon.num_frames) >= k, 1.0, recon.grasped))
    skill = skill_from(held)  # no release: the relation is the last frame's
    carried = apply_skill(skill, box_moved(demonstrated_layout(skill), -0.08, 0.05, math.radians(-20)))
    demo, new = in_box_frame(held, -1), in_box_frame(carried, -1)
    side = int(np.argmax(np.abs(demo[:2])))
    assert np.sign(new[side]) == np.sign(demo[side]) and new[1 - side] == pytest.approx(demo[1 - side], abs=1e-9)
    assert evaluate(carried).success, evaluate(carried).checks


def test_a_carried_objects_tilt_turns_with_its_yaw():
    recon = truth("pick_up")
    tip = np.linspace(0.0, math.pi / 2, recon.num_frames)  # stood on end about world x while lifted
    tilts = np.array([[[1.0, 0.0, 0.0], [0.0, math.cos(a), -math.sin(a)], [0.0, math.sin(a), math.cos(a)]]
                      for a in tip])
    tilted = dataclasses.replace(recon, object_rot=tilts @ recon.object_rot)
    skill = skill_from(tilted)
    layout = demonstrated_layout(skill)
    carried = apply_skill(skill, dataclasses.replace(layout, object=(*layout.object[:2], layout.object[2] + 1.0)))
    np.testing.assert_allclose(carried.object_corners()[..., 2].min(1), tilted.object_corners()[..., 2].min(1),
                               atol=1e-9)  # every frame as high: on the same face, at the demonstrated height
