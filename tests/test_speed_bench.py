"""``warpskill bench speed --set``: the worker's instrumentation and the per-stage figures."""

import pytest
import torch

from warpskill.bench import stage_timing
from warpskill.bench.speed import speed_cases, stage_figures
from warpskill.optimizer.checkpoint import Checkpoint
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.loop import minimise


def test_the_worker_times_each_stage_and_counts_its_iterations(monkeypatch):
    monkeypatch.setattr(stage_timing, "_stages", type(stage_timing._stages)(stage_timing._stages.default_factory))
    x = torch.nn.Parameter(torch.ones(2))
    module = torch.nn.Module()
    module.x = x
    timed = stage_timing._timed_minimise(minimise)
    objective = lambda live: [{"bowl": x.square().sum()}]  # noqa: E731
    timed([module], objective, iterations=7, learning_rate=0.01, config=OptimizeConfig(converge_window=0),
          progress=False, label="bowl", store=Checkpoint(None, ""), coarse=(3, objective))
    stage = stage_timing._stages["bowl"]
    assert stage["iterations"] == 7 and stage["launches"] == 0
    assert 0 < stage["cpu_seconds"] and 0 < stage["seconds"]


def test_stage_figures_are_per_iteration_over_the_set_and_medians_per_case():
    def record(seconds, iterations, launches):
        stage = {"seconds": seconds, "cpu_seconds": seconds / 2, "iterations": iterations, "launches": launches}
        return {"seconds": 2 * seconds, "cpu_seconds": seconds, "stages": {"physics": stage}}

    records = [record(1.0, 100, 300), record(3.0, 100, 500), record(2.0, 200, 400)]
    figures = stage_figures(records, clock="seconds")
    assert figures["physics"]["ms_per_iteration"] == pytest.approx(1e3 * 6.0 / 400)
    assert figures["physics"]["iterations"] == 100 and figures["physics"]["launches"] == 400
    assert figures["video"] == {"median_s": 4.0, "min_s": 2.0, "max_s": 6.0}
    assert stage_figures(records)["physics"]["ms_per_iteration"] == pytest.approx(1e3 * 3.0 / 400)  # CPU time


def test_the_synthetic_set_is_each_action_per_seed():
    cases = speed_cases("synthetic", seeds=2)
    assert len(cases) == 18 and {c["seed"] for c in cases} == {0, 1}
    with pytest.raises(ValueError, match="set must be one of"):
        speed_cases("nope")
