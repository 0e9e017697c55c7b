"""Per-case outcome tables: written, read back, re-evaluated from an output folder, and the flips since a baseline."""

import json
import os
from pathlib import Path

import numpy as np
import pytest
from test_evaluate import scene

from warpskill.bench.outcomes import (
    CaseOutcome,
    RobotRecord,
    close_choices,
    evaluate_folder,
    failed_case,
    flip_report,
    flips,
    folder_outcomes,
    load_outcomes,
    write_outcomes,
)
from warpskill.bench.report import record_outcomes
from warpskill.bench.second_opinion import find_tools, read_truth
from warpskill.bench.settings import TOOLS_VARIABLE, SettingError
from warpskill.cli import main


def _outcomes(*cases):
    return [CaseOutcome(case, "pick_up", ok, () if ok else ("lifted",)) for case, ok in cases]


def test_the_table_round_trips_through_json_and_csv(tmp_path):
    outcomes = [CaseOutcome("pick_up_1", "pick_up", False, ("lifted",), {"scale": 1.7, "centre": 0.2},
                            margins={"above_ground": 0.02, "lifted": -0.004, "started_on_ground": 0.01}),
                failed_case("pick_up_2", "pick_up", "DemonstrationError: no box")]
    path = write_outcomes(tmp_path, outcomes)
    assert load_outcomes(path) == {o.case: o for o in outcomes} == load_outcomes(tmp_path)
    rows = (tmp_path / "outcomes.csv").read_text().splitlines()
    assert rows[0].startswith("case,action,success,failed_checks,closest_check,closest_margin,centre,")
    assert rows[1].startswith("pick_up_1,pick_up,0,lifted,lifted,-0.0040,0.2000,")
    assert rows[2].startswith("pick_up_2,pick_up,0,error,,,,") and rows[2].endswith("DemonstrationError: no box,,")


def test_flips_name_fixed_and_broken_cases_with_their_failed_checks():
    before = {o.case: o for o in _outcomes(("a_1", True), ("a_2", False), ("a_3", True), ("a_4", False))}
    now = {o.case: o for o in _outcomes(("a_1", False), ("a_2", True), ("a_3", True), ("a_5", True))}
    fixed, broken = flips(before, now)
    assert [n.case for _, n in fixed] == ["a_2"] and [n.case for _, n in broken] == ["a_1"]
    report = flip_report(before, now, name="yesterday")
    assert "3 case(s) in both, 2 -> 2 succeed; 1 fixed, 1 broken" in report
    assert "fixed  a_2" in report and "was failing (lifted)" in report
    assert "broken a_1" in report and "now failing (lifted)" in report
    assert "not in yesterday: a_5" in report and "only in yesterday: a_4" in report


def _robot(planned=True, mujoco=True, newton=True, robust=None, misses=()):
    return RobotRecord(planned, {"mujoco": mujoco, "newton": newton}, robust, tuple(misses))


def test_the_robot_step_is_kept_in_the_table_and_its_flips_are_named(tmp_path):
    before = [CaseOutcome("19", "put_next_to", True, robot=_robot()),
              CaseOutcome("3107", "pull_right_to_left", True, robot=_robot(newton=False,
                                                                                misses=["newton replay fails moved_left"])),
              CaseOutcome("601", "push_left_to_right", True)]  # no robot step
    now = [CaseOutcome("19", "put_next_to", True, robot=_robot(robust=False, misses=["not robust: fails under mass x2"])),
           CaseOutcome("3107", "pull_right_to_left", True, robot=_robot()),
           CaseOutcome("601", "push_left_to_right", True, robot=_robot())]
    path = write_outcomes(tmp_path, now)
    assert load_outcomes(path) == {o.case: o for o in now}
    assert [o.robot_success for o in before] == [True, False, None]
    rows = (tmp_path / "outcomes.csv").read_text().splitlines()
    assert rows[0].endswith(",robot,robot_misses") and rows[1].endswith(",0,not robust: fails under mass x2")
    report = flip_report({o.case: o for o in before}, {o.case: o for o in now})
    assert "robot step: 2 case(s) in both, 1 -> 1 succeed; 1 fixed, 1 broken" in report
    assert "fixed  3107" in report and "was missing: newton replay fails moved_left" in report
    assert "broken 19" in report and "now missing: not robust: fails under mass x2" in report


def test_a_table_of_older_code_with_the_robot_step_as_a_plain_object_still_loads(tmp_path):
    old = {"case": "19", "action": "put_next_to", "success": True, "failed_checks": [], "errors": {"noun_ratio": 1.2},
           "note": "", "robot": {"planned": True, "replays": {"mujoco": True, "newton": False}, "robust": None,
                                 "misses": ["newton replay fails moved_left"], "substitute": ""}}
    no_robot = dict(old, case="601", robot={})
    (tmp_path / "outcomes.json").write_text(json.dumps({"cases": [old, no_robot]}))
    table = load_outcomes(tmp_path)
    assert table["19"].robot == _robot(newton=False, misses=["newton replay fails moved_left"])
    assert table["19"].robot_success is False and table["601"].robot is None
    write_outcomes(tmp_path / "again", list(table.values()))  # written back as this code writes it, same outcomes
    assert load_outcomes(tmp_path / "again") == table


def test_an_output_folder_of_older_code_is_re_evaluated_as_a_baseline(tmp_path, capsys):
    lifted = scene([0, 0.6, 0.05], [0, 0.6, 0.2], action="pick_up")
    dropped = scene([0, 0.6, 0.05], [0, 0.6, 0.05], action="pick_up")
    for case, recon in (("pick_up_0", lifted), ("pick_up_1", dropped)):
        (tmp_path / "old" / case).mkdir(parents=True)
        recon.save(tmp_path / "old" / case / "reconstruction.npz")
    outcomes = evaluate_folder(tmp_path / "old")
    assert [(o.case, o.success, o.failed_checks) for o in outcomes] == [("pick_up_0", True, ()),
                                                                      ("pick_up_1", False, ("lifted",))]
    now = folder_outcomes(tmp_path / "old", {"pick_up_0": "pick_up", "pick_up_2": "pick_up"}, {})
    assert now[1] == failed_case("pick_up_2", "pick_up", "no reconstruction")
    record_outcomes(tmp_path / "new", _outcomes(("pick_up_0", False), ("pick_up_1", True)),
                    baseline=tmp_path / "old", save_baseline=tmp_path / "saved.json")
    out = capsys.readouterr().out
    assert "broken pick_up_0" in out and "fixed  pick_up_1" in out
    assert json.loads((tmp_path / "saved.json").read_text())["cases"][0]["case"] == "pick_up_0"
    assert main(["bench", "flips", str(tmp_path / "old"), str(tmp_path / "new")]) == 0
    assert "1 fixed, 1 broken" in capsys.readouterr().out


def test_a_baseline_that_is_no_outcome_table_is_named(tmp_path):
    (tmp_path / "x.json").write_text("{}")
    with pytest.raises(ValueError, match="x.json: not an outcome table"):
        load_outcomes(tmp_path / "x.json")
    with pytest.raises(ValueError, match="neither outcomes.json"):
        load_outcomes(tmp_path)
    with pytest.raises(FileNotFoundError):
        load_outcomes(tmp_path / "missing")


def test_second_opinion_is_skipped_cleanly_without_the_tools(tmp_path, capsys, monkeypatch):
    assert find_tools(tmp_path) is None
    assert main(["bench", "second-opinion", "-o", str(tmp_path / "out"), "--tools", str(tmp_path)]) == 1
    assert "second opinion skipped" in capsys.readouterr().out
    assert not (tmp_path / "out").exists()
    monkeypatch.delenv(TOOLS_VARIABLE, raising=False)  # no folder given: one line naming the option and the variable
    with pytest.raises(SettingError, match=f"--tools or set \\${TOOLS_VARIABLE}"):
        find_tools()
    assert main(["bench", "second-opinion", "-o", str(tmp_path / "out")]) == 1
    assert f"${TOOLS_VARIABLE}" in capsys.readouterr().out


@pytest.mark.slow
def test_the_second_opinion_annotations_read_through_the_real_reader(tmp_path):
    folder = os.environ.get(TOOLS_VARIABLE) or Path(__file__).resolve().parents[2] / "shared" / "tools"
    tools = find_tools(folder) if Path(folder).is_dir() else None
    if tools is None:
        pytest.skip("the shared tools synthdemo.py / synth_sthelse.py are not here")
    from warpskill.bench.second_opinion import generate_annotations
    from warpskill.data.boxes.something_else import read_something_else, something_else_demonstration

    annotations = generate_annotations(tools, tmp_path, ["push_left_to_right"], [3])
    [video] = read_something_else(annotations / "annotations.json", annotations / "phases.csv",
                                  annotations / "actions.csv").values()
    demo, _ = something_else_demonstration(video)
    truth = read_truth(tmp_path / "demos" / "push_left_to_right_s3.npz")
    assert demo.action == "push_left_to_right" and demo.num_frames == len(truth["object_pos"])
    assert demo.contact.any() and np.isfinite(truth["camera_height"])


def _judged(start, fit, behind, *, chosen=False, contradicted=False):
    return {"start": start, "contact_frames": 20, "fit": fit, "ends_behind_static": behind,
            "contradicted": contradicted, "chosen": chosen}


def test_the_closest_choices_are_the_narrowest_fits_between_the_two_sides_of_the_static():
    near = CaseOutcome("6538", "put_behind", True, hypotheses=[
        _judged("stage (a)", 2.0, True, chosen=True), _judged("on the static", 2.1, False),
        _judged("behind the static", 2.05, True)])  # the same side: no rival
    far = CaseOutcome("8801", "put_onto", False, ("over_static",), hypotheses=[
        _judged("stage (a)", 3.0, True, chosen=True), _judged("on the static", 8.0, False)])
    ruled_out = CaseOutcome("7", "put_onto", True, hypotheses=[
        _judged("on the static", 2.0, False, chosen=True), _judged("stage (a)", 1.0, True, contradicted=True)])
    no_static = CaseOutcome("601", "push_left_to_right", True,
                            hypotheses=[_judged("stage (a)", 1.0, None, chosen=True)])
    assert near.choice_gap() == pytest.approx(("stage (a)", "on the static", 0.05))
    assert ruled_out.choice_gap() is None and no_static.choice_gap() is None
    assert close_choices([far, ruled_out, near, no_static]) == (
        "closest choices (the other side of the static fitting worse by): "
        "6538 (ok) stage (a) over on the static by 5 %, 8801 (fail) stage (a) over on the static by 167 %")
    assert close_choices([no_static]) == ""
