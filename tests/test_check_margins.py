"""Each success check's signed margin [m]: its sign is the verdict's, its size how far the scene is from flipping it."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from test_evaluate import scene, with_object_z

from warpskill.bench.outcomes import CaseOutcome, flip_report, judged, load_outcomes, write_outcomes
from warpskill.contract.actions import ACTIONS
from warpskill.contract.evaluation import evaluate
from warpskill.contract.reconstruction import Reconstruction
from warpskill.synthetic import make_demonstration

REGION_CHECKS = {"put_next_to": "next_to_static", "put_in_front_of": "in_front_of_static",
                 "put_behind": "behind_static", "put_onto": "over_static"}


def truth(action: str, seed: int = 0) -> Reconstruction:
    return Reconstruction(**make_demonstration(action, seed=seed, noise="none").truth)


def assert_margins_agree(result) -> None:
    assert list(result.margins) == list(result.checks)
    for name, passed in result.checks.items():
        assert (result.margins[name] >= 0) if passed else (result.margins[name] < 0), (name, result.margins[name])


def failed_final(recon: Reconstruction, action: str) -> np.ndarray:
    """A final object position that fails ``action``: where it started, or for the put actions
    beside the static box, over the static box's centre."""
    if action.startswith("put") and action != "put_onto":
        return np.array([*recon.static_pos[0, :2], recon.object_pos[-1, 2]])
    return recon.object_pos[0]


def with_final_position(recon: Reconstruction, position) -> Reconstruction:
    object_pos = recon.object_pos.copy()
    object_pos[-1] = position
    return dataclasses.replace(recon, object_pos=object_pos)


@pytest.mark.parametrize("action", ACTIONS)
def test_a_true_scene_passes_with_room_and_one_moved_to_fail_fails_by_a_margin(action):
    recon = truth(action)
    result = evaluate(recon)
    assert result.success and min(result.margins.values()) > 0
    assert_margins_agree(result)
    assert result.closest_call() == min(result.margins.items(), key=lambda item: item[1])
    still = evaluate(with_final_position(recon, failed_final(recon, action)))
    assert not still.success and still.closest_call()[1] < 0
    assert_margins_agree(still)
    if action.startswith(("pull", "push")):
        assert still.margins["moved_" + action.split("_")[-1]] == pytest.approx(-0.05)
    if action == "pick_up":
        assert still.margins["lifted"] == pytest.approx(-0.01)


@pytest.mark.parametrize("action", ["pull_left_to_right", "push_right_to_left", "pick_up"])
def test_moving_the_final_object_by_its_margin_flips_the_motion_check(action):
    recon = truth(action, seed=1)
    name = {"pull_left_to_right": "moved_right", "push_right_to_left": "moved_left", "pick_up": "lifted"}[action]
    margin = evaluate(recon).margins[name]
    axis, sign = (2, 1.0) if action == "pick_up" else (0, 1.0 if name == "moved_right" else -1.0)
    for extra, passes in ((-0.001, True), (0.001, False)):
        final = recon.object_pos[-1].copy()
        final[axis] -= sign * (margin + extra)
        moved = evaluate(with_final_position(recon, final))
        assert moved.checks[name] is passes and moved.margins[name] == pytest.approx(-extra, abs=1e-9)


@pytest.mark.parametrize("action", list(REGION_CHECKS))
@pytest.mark.parametrize("seed", [0, 1])
def test_a_region_checks_margin_is_the_final_centres_distance_to_its_edge(action, seed):
    """Shifted by 1 mm less than its margin in any direction the object is still placed; by 1 mm more in
    the edge's direction it is not (the margin is exact inside the region)."""
    recon, name = truth(action, seed), REGION_CHECKS[action]
    margin = evaluate(recon).margins[name]
    assert margin > 0.001
    angles = np.radians(np.arange(0.0, 360.0, 1.0))
    directions = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], axis=1)
    final = recon.object_pos[-1]
    inside = [evaluate(with_final_position(recon, final + (margin - 0.001) * d)) for d in directions[::10]]
    beyond = [evaluate(with_final_position(recon, final + (margin + 0.001) * d)) for d in directions]
    assert all(r.checks[name] and r.margins[name] >= 0 for r in inside)
    assert any(not r.checks[name] for r in beyond)
    for r in inside + beyond:
        assert r.checks[name] == (r.margins[name] >= 0)


def test_the_share_of_frames_checks_measure_the_frame_that_decides():
    # 8 frames, at most 2 may be below -2 cm: the third lowest frame decides above_ground.
    recon = with_object_z(scene([0, 0, 0.05], [0.2, 0, 0.05], action="pull_left_to_right"), [0, 1], -0.1)
    result = evaluate(recon)
    assert result.checks["above_ground"] and result.margins["above_ground"] == pytest.approx(0.02)
    sunk = evaluate(with_object_z(recon, [2], 0.02))  # a third frame's lowest corner at -3 cm
    assert not sunk.checks["above_ground"] and sunk.margins["above_ground"] == pytest.approx(-0.01)
    # The hand axis, 30 deg above the horizontal at azimuth 0: its far end 0.4 cos 30 deg right of the tip.
    assert result.margins["hand_from_right"] == pytest.approx(0.4 * math.cos(math.radians(30)))
    # 7 of 8 frames must be on the right side: with 2 turned to the left, the worse of them decides.
    turned = evaluate(scene([0, 0, 0.05], [0.2, 0, 0.05], action="pull_left_to_right",
                            azimuth_deg=[0, 0, 0, 0, 0, 0, 120, 180]))
    assert not turned.checks["hand_from_right"]
    worse = 0.4 * math.cos(math.radians(30)) * math.cos(math.radians(120))
    assert turned.margins["hand_from_right"] == pytest.approx(worse)


def test_margins_travel_with_the_outcome_table_and_older_tables_still_load(tmp_path):
    kept = {"start": "behind the static", "contact_frames": 9, "fit": 2.5, "ends_behind_static": True,
            "contradicted": False, "chosen": True}
    recon = dataclasses.replace(truth("put_behind"), hypotheses=json.dumps([kept]))
    outcome = judged("7", recon, evaluate(recon))
    assert outcome.margins and outcome.closest_call()[1] > 0 and outcome.closest_text().endswith(" m")
    assert outcome.hypotheses == [kept]
    write_outcomes(tmp_path / "now", [outcome])
    assert load_outcomes(tmp_path / "now")["7"] == outcome
    row = json.loads((tmp_path / "now" / "outcomes.json").read_text())["cases"][0]
    old_row = {key: value for key, value in row.items() if key not in ("margins", "hypotheses")}
    old = dict(old_row, success=False, failed_checks=["behind_static"])
    (tmp_path / "old.json").write_text(json.dumps({"cases": [old]}))
    before = load_outcomes(tmp_path / "old.json")["7"]
    assert before == CaseOutcome("7", "put_behind", False, ("behind_static",), margins={})
    report = flip_report(load_outcomes(tmp_path / "old.json"), {"7": outcome})
    assert "fixed  7" in report and f"behind_static ? -> {outcome.margins['behind_static']:+.3f} m" in report
