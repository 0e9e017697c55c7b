"""Tests for warpskill.evaluate: the paper's success criteria on hand-built trajectories.

Scenes: a 10 cm cube resting on the ground (centre z = 0.05), N = 8 frames moving in a
straight line from ``start`` to ``end``; for put_* a 20 x 20 x 10 cm static box centred at
(0, 0.5), so its xy bounds are x in [-0.1, 0.1], y in [0.4, 0.6] and its top is z = 0.1.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from warpskill.contract.actions import ACTIONS
from warpskill.contract.evaluation import Evaluation, evaluate, success_table
from warpskill.contract.reconstruction import Reconstruction

N = 8
STATIC_CENTRE = (0.0, 0.5, 0.05)


def rotation_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def hand_rotation(azimuth_deg: float) -> np.ndarray:
    """A hand whose axis (local +z) points up at 30 deg towards ``azimuth_deg``."""
    tilt = math.radians(60.0)
    rot_y = np.array([[math.cos(tilt), 0.0, math.sin(tilt)], [0.0, 1.0, 0.0], [-math.sin(tilt), 0.0, math.cos(tilt)]])
    return rotation_z(math.radians(azimuth_deg)) @ rot_y


def scene(
    start,
    end,
    *,
    action: str,
    azimuth_deg=0.0,
    static_yaw: float | None = None,
    object_rot: np.ndarray | None = None,
) -> Reconstruction:
    """A reconstruction whose object moves linearly from ``start`` to ``end`` (xyz [m]).

    ``azimuth_deg``: the hand azimuth, one for all frames or one per frame.
    ``static_yaw``: the static box's yaw [rad]; None for no static object.
    """
    pos = np.linspace(start, end, N)
    azimuths = np.broadcast_to(azimuth_deg, (N,))
    num_static = 0 if static_yaw is None else 1
    return Reconstruction(
        fps=np.array(12.0),
        t=np.arange(N) / 12.0,
        hand_pos=pos + [0.0, 0.0, 0.05],
        hand_rot=np.stack([hand_rotation(a) for a in azimuths]),
        grasp=np.ones(N),
        grasped=np.ones(N),
        object_pos=pos,
        object_rot=np.tile(np.eye(3), (N, 1, 1)) if object_rot is None else object_rot,
        object_size=np.array([0.1, 0.1, 0.1]),
        static_pos=np.reshape(STATIC_CENTRE * num_static, (num_static, 3)),
        static_rot=np.reshape(rotation_z(static_yaw or 0.0), (1, 3, 3))[:num_static],
        static_size=np.reshape([0.2, 0.2, 0.1] * num_static, (num_static, 3)),
        camera_K=np.array([[7.0, 0.0, 4.0], [0.0, 6.0, 3.0], [0.0, 0.0, 1.0]]),
        camera_elevation=np.array(0.4),
        camera_height=np.array(0.5),
        image_size=np.array([6, 8]),
        action=np.array(action),
        loss=np.array(0.0),
    )


def with_object_z(recon: Reconstruction, frames, z: float) -> Reconstruction:
    object_pos = recon.object_pos.copy()
    object_pos[frames, 2] = z
    return dataclasses.replace(recon, object_pos=object_pos)


GROUND = 0.05  # object centre z when resting on the ground
# A successful scene per action.
SUCCESS = {
    "pull_left_to_right": dict(start=(0.0, 0.5, GROUND), end=(0.2, 0.5, GROUND), azimuth_deg=0.0),
    "push_right_to_left": dict(start=(0.0, 0.5, GROUND), end=(-0.2, 0.5, GROUND), azimuth_deg=10.0),
    "pull_right_to_left": dict(start=(0.0, 0.5, GROUND), end=(-0.2, 0.5, GROUND), azimuth_deg=180.0),
    "push_left_to_right": dict(start=(0.0, 0.5, GROUND), end=(0.2, 0.5, GROUND), azimuth_deg=-170.0),
    "pick_up": dict(start=(0.0, 0.5, GROUND), end=(0.0, 0.5, 0.2)),
    "put_next_to": dict(start=(0.3, 0.1, GROUND), end=(0.25, 0.5, GROUND), static_yaw=0.0),
    "put_in_front_of": dict(start=(0.3, 0.1, GROUND), end=(0.0, 0.25, GROUND), static_yaw=0.0),
    "put_behind": dict(start=(0.3, 0.1, GROUND), end=(0.0, 0.75, GROUND), static_yaw=0.0),
    "put_onto": dict(start=(0.3, 0.1, GROUND), end=(0.05, 0.52, 0.15), static_yaw=0.0),
}

CHECK_NAMES = {
    "pull_left_to_right": ["above_ground", "moved_right", "stayed_on_ground", "hand_from_right"],
    "push_right_to_left": ["above_ground", "moved_left", "stayed_on_ground", "hand_from_right"],
    "pull_right_to_left": ["above_ground", "moved_left", "stayed_on_ground", "hand_from_left"],
    "push_left_to_right": ["above_ground", "moved_right", "stayed_on_ground", "hand_from_left"],
    "pick_up": ["above_ground", "lifted", "started_on_ground"],
    "put_next_to": ["above_ground", "next_to_static", "below_static_top"],
    "put_in_front_of": ["above_ground", "in_front_of_static", "below_static_top"],
    "put_behind": ["above_ground", "behind_static", "below_static_top"],
    "put_onto": ["above_ground", "over_static", "on_static_top"],
}


def success_scene(action: str, **changes) -> Reconstruction:
    return scene(**{**SUCCESS[action], **changes}, action=action)


def assert_fails_only(result: Evaluation, check: str) -> None:
    """``check`` fails, every other check passes, so the evaluation fails."""
    assert not result.success
    assert [name for name, passed in result.checks.items() if not passed] == [check]


@pytest.mark.parametrize("action", ACTIONS)
@pytest.mark.parametrize("mode", ["strict", "original"])
def test_success(action, mode):
    result = evaluate(success_scene(action), mode=mode)
    assert (result.success, result.checks, result.action) == (True, dict.fromkeys(result.checks, True), action)
    assert list(result.margins) == list(result.checks) and min(result.margins.values()) > 0
    expected = CHECK_NAMES[action]
    if mode == "original" and action in ("pull_right_to_left", "push_left_to_right"):
        expected = expected[:-1]
    assert list(result.checks) == expected


@pytest.mark.parametrize("action", ACTIONS)
def test_above_ground_allows_a_quarter_of_frames_below(action):
    recon = success_scene(action)
    # Centre z = 0.02: the lowest corner is at -0.03, below the -0.02 allowed.
    assert evaluate(with_object_z(recon, [2, 3], 0.02)).success  # 2 of 8 frames: 25%
    assert_fails_only(evaluate(with_object_z(recon, [2, 3, 4], 0.02)), "above_ground")
    assert evaluate(with_object_z(recon, [2, 3, 4], 0.035)).success  # lowest corner -0.015


LATERAL = ["pull_left_to_right", "push_right_to_left", "pull_right_to_left", "push_left_to_right"]


@pytest.mark.parametrize("action", LATERAL)
def test_lateral_motion_needs_five_centimetres(action):
    direction = 1.0 if action.endswith("left_to_right") else -1.0
    check = "moved_right" if direction > 0 else "moved_left"
    assert evaluate(success_scene(action, end=(0.051 * direction, 0.5, GROUND))).success
    assert_fails_only(evaluate(success_scene(action, end=(0.049 * direction, 0.5, GROUND))), check)
    assert_fails_only(evaluate(success_scene(action, end=(-0.2 * direction, 0.5, GROUND))), check)


@pytest.mark.parametrize("action", LATERAL)
def test_lateral_object_stays_on_ground(action):
    recon = success_scene(action)
    # The cube's vertical extent is 0.1 m: a centre z range of 0.099 passes, 0.1 fails.
    assert evaluate(with_object_z(recon, [4], GROUND + 0.099)).success
    assert_fails_only(evaluate(with_object_z(recon, [4], GROUND + 0.1)), "stayed_on_ground")


def test_lateral_extent_counts_the_rotated_object():
    # Tilted 45 deg about x, the cube's vertical extent is 0.1 * sqrt(2) = 0.141 m.
    c = math.cos(math.pi / 4)
    tilted = np.array([[1.0, 0.0, 0.0], [0.0, c, -c], [0.0, c, c]])
    rot = np.tile(np.eye(3), (N, 1, 1))
    rot[5] = tilted
    recon = with_object_z(success_scene("pull_left_to_right", object_rot=rot), [4], GROUND + 0.12)
    assert evaluate(recon).success
    assert_fails_only(evaluate(with_object_z(recon, [4], GROUND + 0.15)), "stayed_on_ground")


@pytest.mark.parametrize("action", LATERAL)
def test_hand_azimuth_side_in_more_than_three_quarters_of_frames(action):
    good = SUCCESS[action]["azimuth_deg"]
    wrong = good + 180.0
    check = "hand_from_right" if abs(good) < 90 else "hand_from_left"
    seven_of_eight = [good] * 7 + [wrong]
    six_of_eight = [good] * 6 + [wrong] * 2  # 75%: not more than 75%
    assert evaluate(success_scene(action, azimuth_deg=seven_of_eight)).success
    assert_fails_only(evaluate(success_scene(action, azimuth_deg=six_of_eight)), check)
    assert_fails_only(evaluate(success_scene(action, azimuth_deg=wrong)), check)


@pytest.mark.parametrize("action", LATERAL)
def test_original_mode_skips_hand_from_left(action):
    good = SUCCESS[action]["azimuth_deg"]
    wrong_side = success_scene(action, azimuth_deg=good + 180.0)
    original = evaluate(wrong_side, mode="original")
    if abs(good) < 90:  # hand_from_right: checked in both modes
        assert not original.success and not original.checks["hand_from_right"]
    else:
        assert original.success and "hand_from_left" not in original.checks
        assert not evaluate(wrong_side).success


def test_pick_up():
    assert evaluate(success_scene("pick_up", end=(0.0, 0.5, GROUND + 0.011))).success
    assert_fails_only(evaluate(success_scene("pick_up", end=(0.0, 0.5, GROUND + 0.009))), "lifted")
    assert_fails_only(evaluate(success_scene("pick_up", end=(0.0, 0.5, GROUND))), "lifted")
    # The lowest corner at frame 0 must be below 1 cm.
    assert evaluate(success_scene("pick_up", start=(0.0, 0.5, GROUND + 0.009))).success
    assert_fails_only(evaluate(success_scene("pick_up", start=(0.0, 0.5, GROUND + 0.011))), "started_on_ground")


# Final object centres around the static box, x in [-0.1, 0.1], y in [0.4, 0.6].
LEFT, RIGHT = (-0.25, 0.5), (0.25, 0.5)
FRONT, BEHIND = (0.0, 0.25), (0.0, 0.75)
FRONT_RIGHT_DIAGONAL = (0.35, 0.1)  # br = -50 deg, tr = -63 deg: within 60 deg of "right"
FAR_FRONT_RIGHT = (0.2, 0.0)  # br = -76 deg: outside


@pytest.mark.parametrize(
    "action, check, passing, failing",
    [
        ("put_next_to", "next_to_static", [LEFT, RIGHT, FRONT_RIGHT_DIAGONAL], [FRONT, BEHIND, FAR_FRONT_RIGHT]),
        ("put_in_front_of", "in_front_of_static", [FRONT, (0.15, 0.2)], [BEHIND, LEFT, RIGHT, (0.3, 0.3)]),
        ("put_behind", "behind_static", [BEHIND, (-0.15, 0.8)], [FRONT, LEFT, RIGHT, (-0.3, 0.7)]),
    ],
)
def test_placement(action, check, passing, failing):
    for x, y in passing:
        assert evaluate(success_scene(action, end=(x, y, GROUND))).success, (x, y)
    for x, y in failing:
        assert_fails_only(evaluate(success_scene(action, end=(x, y, GROUND))), check)


@pytest.mark.parametrize("action", ["put_next_to", "put_in_front_of", "put_behind"])
def test_placement_object_below_static_top(action):
    x, y, _ = SUCCESS[action]["end"]
    # The static top is z = 0.1; the lowest object corner is 0.05 below the centre.
    assert evaluate(success_scene(action, end=(x, y, 0.149))).success
    assert_fails_only(evaluate(success_scene(action, end=(x, y, 0.151))), "below_static_top")


def test_placement_uses_rotated_static_bounds():
    # Yawed 45 deg, the box's xy bounds grow to x in [-0.141, 0.141]: a centre at x = 0.13
    # is beside the axis-aligned box but inside the rotated one's bounds.
    assert evaluate(success_scene("put_next_to", end=(0.13, 0.5, GROUND))).success
    rotated = success_scene("put_next_to", end=(0.13, 0.5, GROUND), static_yaw=math.pi / 4)
    assert_fails_only(evaluate(rotated), "next_to_static")


def test_put_onto_footprint_and_original_mode():
    inside = success_scene("put_onto", end=(0.09, -0.09 + 0.5, 0.15))
    assert evaluate(inside).success
    beyond = success_scene("put_onto", end=(0.15, 0.5, 0.15))  # half-size 0.1 < 0.15 < size 0.2
    assert_fails_only(evaluate(beyond), "over_static")
    assert evaluate(beyond, mode="original").success
    far = success_scene("put_onto", end=(0.0, 0.75, 0.15))
    assert_fails_only(evaluate(far, mode="original"), "over_static")


def test_put_onto_uses_static_frame():
    # Yawed 45 deg, the point (0.12, 0.5) is at (0.085, -0.085) in the box's frame: inside.
    # (0, 0.62) is at (0.088, 0.088) in the rotated box, outside the axis-aligned one.
    rotated = dict(static_yaw=math.pi / 4)
    assert evaluate(success_scene("put_onto", end=(0.12, 0.5, 0.15), **rotated)).success
    assert_fails_only(evaluate(success_scene("put_onto", end=(0.12, 0.5, 0.15))), "over_static")
    assert evaluate(success_scene("put_onto", end=(0.0, 0.62, 0.15), **rotated)).success
    assert_fails_only(evaluate(success_scene("put_onto", end=(0.0, 0.62, 0.15))), "over_static")


def test_put_onto_rests_on_static_top():
    # The top is z = 0.1; the lowest object corner is 0.05 below the centre.
    for z in (0.121, 0.179):
        assert evaluate(success_scene("put_onto", end=(0.05, 0.52, z))).success, z
    for z in (0.119, 0.181, GROUND):
        assert_fails_only(evaluate(success_scene("put_onto", end=(0.05, 0.52, z))), "on_static_top")


def test_action_argument_overrides_and_defaults():
    recon = success_scene("pick_up")
    assert evaluate(recon).action == "pick_up"
    assert evaluate(recon, "pull_left_to_right").action == "pull_left_to_right"
    unknown = dataclasses.replace(recon, action=None)
    with pytest.raises(ValueError, match="unknown action ''"):
        evaluate(unknown)
    with pytest.raises(ValueError, match="valid actions: pull_left_to_right"):
        evaluate(recon, "throw")
    with pytest.raises(ValueError, match="unknown mode"):
        evaluate(recon, mode="lenient")


@pytest.mark.parametrize("action", ["put_next_to", "put_in_front_of", "put_behind", "put_onto"])
def test_put_needs_a_static_object(action):
    with pytest.raises(ValueError, match=f"{action} needs a static object"):
        evaluate(success_scene("pick_up"), action)


def test_evaluation_is_frozen():
    result = evaluate(success_scene("pick_up"))
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.success = False


def test_success_table():
    rows = {
        "initialisation only": [("pick_up", True), ("pick_up", False), ("put_onto", False)],
        "full method": [("pick_up", True), ("pick_up", True), ("put_onto", True)],
    }
    lines = success_table(rows).splitlines()
    assert len(lines) == 4
    assert len({len(line) for line in lines}) == 1  # aligned
    cells = [[cell.strip() for cell in line.strip("|").split("|")] for line in lines]
    assert cells[0] == ["method", *ACTIONS, "total", "%"]
    assert all(set(cell) == {"-"} for cell in cells[1])
    pick_up, put_onto = 1 + ACTIONS.index("pick_up"), 1 + ACTIONS.index("put_onto")
    first, second = cells[2], cells[3]
    assert first[0] == "initialisation only" and second[0] == "full method"
    assert (first[pick_up], first[put_onto], first[-2], first[-1]) == ("1/2", "0/1", "1/3", "33.3")
    assert (second[pick_up], second[put_onto], second[-2], second[-1]) == ("2/2", "1/1", "3/3", "100.0")
    assert first[1 + ACTIONS.index("put_behind")] == "-"


def test_success_table_edge_cases():
    empty = success_table({"nothing run": []}).splitlines()[2]
    assert [c.strip() for c in empty.strip("|").split("|")][-2:] == ["0/0", "-"]
    with pytest.raises(ValueError, match="unknown action 'throw'"):
        success_table({"method": [("throw", True)]})
