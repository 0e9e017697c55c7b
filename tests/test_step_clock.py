"""The seconds a command's steps take: ``cli.common.StepClock``, printed and written as ``timing.json``."""

import json

from warpskill.cli.common import StepClock


def test_each_step_is_timed_added_up_and_written(tmp_path, capsys):
    clock = StepClock()
    for name in ("prepare", "optimize", "prepare"):
        with clock.step(name):
            sum(range(10_000))
    assert list(clock.steps) == ["prepare", "optimize"]
    clock.report(tmp_path / "out" / "timing.json")
    written = json.loads((tmp_path / "out" / "timing.json").read_text())
    assert written["steps"] == clock.steps
    assert written["seconds"] == sum(step["seconds"] for step in clock.steps.values())
    line = capsys.readouterr().out.strip()
    assert line.startswith("seconds: prepare ") and ", optimize " in line and line.endswith(f"({tmp_path / 'out' / 'timing.json'})")


def test_a_step_that_raises_is_timed_and_nothing_is_written_without_steps(tmp_path, capsys):
    clock = StepClock()
    try:
        with clock.step("prepare"):
            raise ValueError("refused")
    except ValueError:
        pass
    assert set(clock.steps) == {"prepare"}
    StepClock().report(tmp_path / "timing.json")
    assert not (tmp_path / "timing.json").exists() and capsys.readouterr().out == ""
