"""The skill record: what a video teaches relative to the objects, saved, and carried to new layouts."""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest

from warpskill.contract import Layout, LayoutError, Reconstruction, Skill, SkillError, evaluate
from warpskill.geometry import heading
from warpskill.robot.skill_layout import GRAZE, apply_skill, demonstrated_layout, overlap_depth, skill_from
from warpskill.synthetic import make_demonstration

MOTION_KEYS = ("object_pos", "object_rot", "hand_pos", "hand_rot", "static_pos", "static_rot")


@functools.cache
def truth(action: str, seed: int = 0) -> Reconstruction:
    """The ground truth of a synthetic demonstration (made once per test run; never modified)."""
    return Reconstruction(**make_demonstration(action, seed=seed, noise="none").truth)


def rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def moved(layout: Layout, dx: float, dy: float, dyaw: float, *, statics: bool = True) -> Layout:
    """``layout`` with the object (and the static boxes) shifted by (dx, dy) [m] and turned by dyaw [rad]."""
    shift = lambda pose: (pose[0] + dx, pose[1] + dy, pose[2] + dyaw)  # noqa: E731
    return dataclasses.replace(layout, object=shift(layout.object),
                               statics=tuple(map(shift, layout.statics)) if statics else layout.statics)


@pytest.mark.parametrize("action", ["push_left_to_right", "pull_right_to_left", "pick_up", "put_behind", "put_onto"])
def test_identity_layout_reproduces_the_reconstruction(action):
    recon = truth(action)
    skill = skill_from(recon)
    again = apply_skill(skill, demonstrated_layout(skill))
    for key in MOTION_KEYS:
        np.testing.assert_allclose(getattr(again, key), getattr(recon, key), atol=1e-12, err_msg=key)
    np.testing.assert_array_equal(again.grasped, recon.grasped)
    assert str(again.action) == action and again.fps == recon.fps


def test_save_and_load_round_trip(tmp_path):
    skill = skill_from(truth("put_behind"))
    skill.save(tmp_path / "skill.npz")
    loaded = Skill.load(tmp_path / "skill.npz")
    for field in dataclasses.fields(Skill):
        np.testing.assert_array_equal(np.asarray(getattr(loaded, field.name)), np.asarray(getattr(skill, field.name)),
                                      err_msg=field.name)
    assert demonstrated_layout(loaded) == demonstrated_layout(skill)
    assert loaded.onset == pytest.approx(skill.onset) and math.isfinite(loaded.release)


def test_the_object_noun_is_kept_saved_and_carried_to_a_layout(tmp_path):
    skill = skill_from(dataclasses.replace(truth("put_behind"), object_noun=np.array("mug")))
    assert skill.object_noun == "mug"
    skill.save(tmp_path / "skill.npz")
    loaded = Skill.load(tmp_path / "skill.npz")
    assert loaded.object_noun == "mug"
    laid = apply_skill(loaded, moved(demonstrated_layout(loaded), 0.05, -0.03, math.radians(40)))
    assert str(laid.object_noun) == "mug"  # the layout's replay holds the person's mug


def test_a_skill_file_without_the_noun_loads_unnamed(tmp_path):
    skill = skill_from(truth("put_behind"))
    assert skill.object_noun == ""
    skill.save(tmp_path / "unnamed.npz")  # an unknown noun is written as before the key
    with np.load(tmp_path / "unnamed.npz") as unnamed:
        assert "object_noun" not in unnamed.files
    old = {field.name: np.asarray(getattr(skill, field.name)) for field in dataclasses.fields(Skill)
           if field.name != "object_noun"}
    np.savez(tmp_path / "old.npz", **old)  # a file written before the key
    loaded = Skill.load(tmp_path / "old.npz")
    assert loaded.object_noun == "" and str(apply_skill(loaded, demonstrated_layout(loaded)).object_noun) == ""


def test_load_names_the_bad_key(tmp_path):
    skill = skill_from(truth("pick_up"))
    arrays = {field.name: np.asarray(getattr(skill, field.name)) for field in dataclasses.fields(Skill)}
    np.savez(tmp_path / "short.npz", **{k: v for k, v in arrays.items() if k != "hand_in_object_pos"})
    with pytest.raises(SkillError, match="missing key.*hand_in_object_pos"):
        Skill.load(tmp_path / "short.npz")
    np.savez(tmp_path / "bad.npz", **{**arrays, "object_motion_pos": arrays["object_motion_pos"][:-1]})
    with pytest.raises(SkillError, match="object_motion_pos: expected shape"):
        Skill.load(tmp_path / "bad.npz")
    np.savez(tmp_path / "nouns.npz", **{**arrays, "object_noun": np.array(["mug", "cup"])})
    with pytest.raises(SkillError, match="object_noun: expected one string"):
        Skill.load(tmp_path / "nouns.npz")


@pytest.mark.parametrize("action", ["push_left_to_right", "pull_right_to_left"])
def test_pull_and_push_keep_their_world_direction(action):
    recon = truth(action)
    skill = skill_from(recon)
    dx, dy, dyaw = 0.07, -0.05, math.radians(35)
    carried = apply_skill(skill, moved(demonstrated_layout(skill), dx, dy, dyaw))
    # The path is the demonstrated one, translated: left to right stays left to right.
    np.testing.assert_allclose(carried.object_pos - carried.object_pos[0], recon.object_pos - recon.object_pos[0],
                               atol=1e-12)
    np.testing.assert_allclose(carried.object_pos[0, :2], recon.object_pos[0, :2] + (dx, dy), atol=1e-12)
    # The object itself is turned about z by the layout's yaw, its motion's rotation kept.
    np.testing.assert_allclose(carried.object_rot, recon.object_rot @ recon.object_rot[0].T @ rot_z(dyaw)
                               @ recon.object_rot[0], atol=1e-12)
    assert heading(carried.object_rot[0]) == pytest.approx(heading(recon.object_rot[0]) + dyaw)
    assert evaluate(carried).success, evaluate(carried).checks


def test_push_contact_follows_the_face_that_faces_the_push():
    recon = truth("push_left_to_right")
    skill = skill_from(recon)
    k_on = int(np.flatnonzero(recon.grasped > 0.5)[0])
    carried = apply_skill(skill, moved(demonstrated_layout(skill), 0.0, 0.0, math.pi / 2))  # the object's y now spans world x
    size = recon.object_size
    before = recon.hand_pos[k_on, 0] - recon.object_pos[k_on, 0]
    after = carried.hand_pos[k_on, 0] - carried.object_pos[k_on, 0]
    assert after - before == pytest.approx(-(size[1] - size[0]) / 2)  # the pushed face moved out by half the change
    np.testing.assert_allclose(carried.hand_rot, recon.hand_rot, atol=1e-12)


def test_grasp_rotates_with_the_object():
    recon = truth("pick_up")
    skill = skill_from(recon)
    dyaw = math.radians(60)
    carried = apply_skill(skill, moved(demonstrated_layout(skill), 0.05, 0.02, dyaw))
    for k in (0, 20, recon.num_frames - 1):  # the hand in the object's frame is the demonstrated one
        np.testing.assert_allclose(carried.object_rot[k].T @ (carried.hand_pos[k] - carried.object_pos[k]),
                                   recon.object_rot[k].T @ (recon.hand_pos[k] - recon.object_pos[k]), atol=1e-12)
        np.testing.assert_allclose(carried.object_rot[k].T @ carried.hand_rot[k],
                                   recon.object_rot[k].T @ recon.hand_rot[k], atol=1e-12)
    lift = recon.object_pos[-1, 2] - recon.object_pos[0, 2]
    assert carried.object_pos[-1, 2] - carried.object_pos[0, 2] == pytest.approx(lift)


def test_put_behind_releases_behind_the_moved_static_box():
    recon = truth("put_behind")
    skill = skill_from(recon)
    layout = demonstrated_layout(skill)
    static = (layout.statics[0][0] + 0.12, layout.statics[0][1] + 0.05, layout.statics[0][2] + math.pi / 2)
    carried = apply_skill(skill, dataclasses.replace(layout, statics=(static,)))
    k_off = int(np.flatnonzero(recon.grasped > 0.5)[-1]) + 1
    demo_offset = recon.object_pos[k_off] - recon.static_pos[0]
    new_offset = carried.object_pos[k_off] - carried.static_pos[0]
    assert new_offset[0] == pytest.approx(demo_offset[0])  # the lateral offset (world x) is kept
    # Behind (world +y): the gap between the box's and the object's world extents is kept.
    def gap(r: Reconstruction, offset: np.ndarray) -> float:
        extents = [0.5 * float(np.abs(rot[1]) @ size) for rot, size in
                   ((r.static_rot[0], r.static_size[0]), (r.object_rot[k_off], r.object_size))]
        return offset[1] - sum(extents)

    assert gap(carried, new_offset) == pytest.approx(gap(recon, demo_offset))
    np.testing.assert_allclose(carried.object_pos[0], recon.object_pos[0], atol=1e-12)  # the start stays
    np.testing.assert_allclose(carried.object_pos[k_off:, 2], recon.object_pos[k_off:, 2], atol=1e-12)
    assert evaluate(carried).success, evaluate(carried).checks


def test_a_carried_object_is_lifted_over_a_box_in_its_way():
    recon = truth("put_behind")
    # A static box 20 cm tall: the demonstrated carry (bottom up to 17.8 cm) would run 2.2 cm into it.
    tall = dataclasses.replace(recon, static_pos=recon.static_pos * (1, 1, 0) + (0, 0, 0.10),
                               static_size=recon.static_size * (1, 1, 0) + (0, 0, 0.20))
    carried = apply_skill(skill_from(tall), demonstrated_layout(skill_from(tall)))
    depths = [overlap_depth(carried.object_pos[f], carried.object_rot[f], carried.object_size, carried.static_pos[0],
                            carried.static_rot[0], carried.static_size[0]) for f in range(carried.num_frames)]
    assert max(depths) == 0.0
    lift = carried.object_pos[:, 2] - recon.object_pos[:, 2]
    held = np.flatnonzero(recon.grasped > 0.5)
    assert not lift[:held[0]].any() and not lift[held[-1] + 1:].any()  # resting frames stay
    carry_top = (recon.object_pos[:, 2] - 0.5 * recon.object_size[2]).max()
    assert lift.max() == pytest.approx(0.20 + 0.01 - carry_top, abs=1e-6)  # 1 cm above the box's top
    np.testing.assert_allclose(carried.hand_pos - recon.hand_pos, carried.object_pos - recon.object_pos, atol=1e-9)
    assert evaluate(carried).success, evaluate(carried).checks


def test_a_release_inside_the_box_is_carried_as_touching_it():
    recon = truth("put_next_to")
    k_off = int(np.flatnonzero(recon.grasped > 0.5)[-1]) + 1
    box_rot = recon.static_rot[0]
    local = box_rot.T @ (recon.object_pos[k_off] - recon.static_pos[0])
    axis = int(np.argmax(np.abs(local[:2])))  # the side of the box the object was put at, in its frame
    out = math.copysign(1.0, local[axis]) * box_rot[:, axis]
    skill = skill_from(recon)
    # The box moved out toward the released object until they overlap by 2 cm at the release.
    inside = dataclasses.replace(recon, static_pos=recon.static_pos + out * (skill.release_gap + 0.02))
    pressed = skill_from(inside)
    assert pressed.release_gap == pytest.approx(-0.02)
    carried = apply_skill(pressed, demonstrated_layout(pressed))
    extents = [0.5 * float(np.abs(rot.T @ out) @ size) for rot, size in
               ((carried.static_rot[0], carried.static_size[0]), (carried.object_rot[k_off], carried.object_size))]
    gap = float((carried.object_pos[k_off] - carried.static_pos[0]) @ out) - sum(extents)
    assert gap == pytest.approx(0.0, abs=1e-9)


def test_an_object_put_onto_the_box_stands_on_its_top_from_the_release_on():
    recon = truth("put_onto")
    k_off = int(np.flatnonzero(recon.grasped > 0.5)[-1]) + 1
    # The physics' contact lets a resting object sink into the box: here 1.5 cm by the end,
    # deeper than a layout tolerates between boxes.
    sink = np.zeros(recon.num_frames)
    sink[k_off:] = np.linspace(0.0, 0.015, recon.num_frames - k_off)
    sunk = dataclasses.replace(recon, object_pos=recon.object_pos - sink[:, None] * (0.0, 0.0, 1.0))
    skill = skill_from(sunk)
    carried = apply_skill(skill, moved(demonstrated_layout(skill), 0.05, -0.03, 0.3))
    top = carried.static_corners()[0, :, 2].max()
    bottoms = carried.object_corners()[k_off:, :, 2].min(1)
    truth_bottoms = recon.object_corners()[k_off:, :, 2].min(1)
    np.testing.assert_allclose(bottoms, np.maximum(truth_bottoms - sink[k_off:], top - GRAZE), atol=1e-9)
    assert bottoms.min() < top  # resting as deep as demonstrated, down to GRAZE
    assert evaluate(carried).success, evaluate(carried).checks


def test_resized_object_keeps_its_bottom():
    recon = truth("put_onto")
    skill = skill_from(recon)
    bigger = tuple(recon.object_size * (1.0, 1.0, 1.4))
    carried = apply_skill(skill, dataclasses.replace(demonstrated_layout(skill), object_size=bigger))
    np.testing.assert_allclose(carried.object_corners()[..., 2].min(1), recon.object_corners()[..., 2].min(1),
                               atol=1e-9)


@pytest.mark.parametrize("change, why", [
    (lambda s: dataclasses.replace(demonstrated_layout(s), statics=()), "places 0 static box.*has 1"),
    (lambda s: dataclasses.replace(demonstrated_layout(s), object=(*demonstrated_layout(s).statics[0][:2], 0.0)),
     "object's start overlaps static box 0"),
])
def test_impossible_layouts_are_refused_in_one_line(change, why):
    skill = skill_from(truth("put_next_to"))
    with pytest.raises(LayoutError, match=why) as error:
        apply_skill(skill, change(skill))
    assert "\n" not in str(error.value) and str(error.value).startswith("layout refused: ")


def test_overlapping_static_boxes_are_refused():
    recon = truth("put_next_to")
    far = recon.static_pos + (0.0, 0.4, 0.0)  # a second box, well behind the scene
    two = dataclasses.replace(recon, static_pos=np.r_[recon.static_pos, far],
                              static_rot=np.r_[recon.static_rot, recon.static_rot],
                              static_size=np.r_[recon.static_size, recon.static_size])
    skill = skill_from(two)
    apply_skill(skill, demonstrated_layout(skill))
    stacked = dataclasses.replace(demonstrated_layout(skill), statics=(demonstrated_layout(skill).statics[0],) * 2)
    with pytest.raises(LayoutError, match=r"static boxes 0 and 1 overlap \(\d+\.\d cm deep\)"):
        apply_skill(skill, stacked)


def test_a_push_into_a_static_box_is_refused():
    recon = truth("push_left_to_right")
    skill = skill_from(recon)
    end = recon.object_pos[-1]
    box = dataclasses.replace(recon, static_pos=end[None] + (0.0, 0.0, 0.0), static_rot=np.eye(3)[None],
                              static_size=np.array([[0.05, 0.05, 0.1]]))
    with pytest.raises(LayoutError, match="object's path at t = .* overlaps static box 0"):
        apply_skill(skill_from(box), demonstrated_layout(skill_from(box)))
    assert skill.num_static == 0


def test_bad_layouts_and_skills():
    with pytest.raises(LayoutError, match="object's pose must be finite"):
        Layout(object=(0.0, math.nan, 0.0))
    with pytest.raises(LayoutError, match="object size must be 3 positive"):
        Layout(object=(0.0, 0.0, 0.0), object_size=(0.1, 0.0, 0.1))
    recon = truth("pick_up")
    with pytest.raises(SkillError, match="never holds"):
        skill_from(dataclasses.replace(recon, grasped=np.zeros(recon.num_frames)))
    with pytest.raises(SkillError, match="action is unknown"):
        skill_from(dataclasses.replace(recon, action=np.array("")))


def test_layout_arrays_round_trip():
    layout = Layout(object=(0.1, 0.6, 0.3), statics=((-0.1, 0.7, 0.0),), object_size=(0.05, 0.06, 0.07))
    assert Layout.from_arrays(layout.to_arrays()) == layout
    assert Layout.from_arrays({}) is None
    assert "17.2 deg" in layout.describe()


def test_an_object_carried_in_and_set_down_soon_stays_on_the_table_in_a_layout():
    # Held from the first frame 8 cm up, it comes down to the table by the grasp's onset and is then
    # carried as demonstrated: started lowered onto the table, its path must not run under it
    # while the lowering shrinks toward the release.
    recon = truth("put_in_front_of")
    k_on = int(np.flatnonzero(recon.grasped > 0.5)[0])
    descent = np.linspace(1.0, 0.0, k_on)[:, None] * np.array([[-0.05, 0.0, 0.08]])
    object_pos, hand_pos, grasped = recon.object_pos.copy(), recon.hand_pos.copy(), recon.grasped.copy()
    object_pos[:k_on] = recon.object_pos[k_on] + descent
    hand_pos[:k_on] = recon.hand_pos[k_on] + descent
    grasped[:k_on] = 1.0
    carried_in = dataclasses.replace(recon, object_pos=object_pos, hand_pos=hand_pos, grasped=grasped)
    laid = apply_skill(skill_from(carried_in), demonstrated_layout(skill_from(carried_in)))
    bottoms = laid.object_corners()[:, :, 2].min(axis=1)
    demonstrated = carried_in.object_corners()[:, :, 2].min(axis=1)
    assert np.all(bottoms >= np.minimum(demonstrated, 0.0) - 1e-9)  # no lower than the table, or the demonstration
    np.testing.assert_allclose(bottoms[0], 0.0, atol=1e-9)  # started on the table
    assert evaluate(laid).checks["above_ground"]
