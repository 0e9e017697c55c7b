"""The worker of ``warpskill bench speed --set``: per-stage timing of :func:`warpskill.optimize`, one case at a time.

Run as a script with ``PYTHONPATH`` at a checkout, it times that checkout's code (with
arguments, ``stage_timing.py run CLIP ...``, it runs that checkout's command line instead:
``bench speed --clip``'s process, timed from outside). Without arguments it reads
one case per line on stdin (JSON, :func:`demonstration`) and writes one JSON line per case:
``{"case", "seconds", "cpu_seconds", "stages": {label: {"seconds", "cpu_seconds", "iterations",
"launches"}}}`` (wall and process CPU time: on a busy machine the CPU time is the steadier). It
instruments from outside (the pipeline's ``minimise`` and ``warp.launch``), so an older
commit is measured exactly as the current one.
"""

from __future__ import annotations

import importlib.util
import json
import os
import sys
import time
from collections import defaultdict
from pathlib import Path

import torch
import warp as wp


def _own_kernels(root: Path) -> None:
    """Import ``warpskill.kernels`` from ``root/kernels``: the package maps it there, and an
    editable install of another checkout would otherwise supply its own."""
    init = root / "kernels" / "__init__.py"
    spec = importlib.util.spec_from_file_location("warpskill.kernels", init,
                                                  submodule_search_locations=[str(init.parent)])
    module = importlib.util.module_from_spec(spec)
    sys.modules["warpskill.kernels"] = module
    spec.loader.exec_module(module)


_count = {"launches": 0}
_stages: dict[str, dict[str, float]] = defaultdict(
    lambda: {"seconds": 0.0, "cpu_seconds": 0.0, "iterations": 0, "launches": 0})


def _counting_launch(launch):
    def counted(*args, **kwargs):
        _count["launches"] += 1
        return launch(*args, **kwargs)
    return counted


def _counting_objective(objective, stage: dict):
    def counted(live):
        stage["iterations"] += 1
        return objective(live)
    return counted


def _timed_minimise(minimise):
    """``minimise`` that adds its seconds (wall and CPU), objective calls (iterations) and Warp
    launches to its label's stage."""

    def timed(modules, objective, **kwargs):
        stage = _stages[kwargs["label"]]
        if kwargs.get("coarse"):
            kwargs["coarse"] = (kwargs["coarse"][0], _counting_objective(kwargs["coarse"][1], stage))
        launches, start, cpu = _count["launches"], time.perf_counter(), time.process_time()
        try:
            return minimise(modules, _counting_objective(objective, stage), **kwargs)
        finally:
            stage["seconds"] += time.perf_counter() - start
            stage["cpu_seconds"] += time.process_time() - cpu
            stage["launches"] += _count["launches"] - launches
    return timed


def demonstration(case: dict):
    """The case's demonstration and its optimisation seed: ``{"set": "dev", "video", "folder"}`` (a
    Something-Else development video) or ``{"set": "synthetic", "action", "seed"}``."""
    if case["set"] == "dev":
        from warpskill.data import read_something_else, something_else_demonstration  # any release's package names

        folder = case["folder"]
        table = read_something_else(f"{folder}/annotations.json", f"{folder}/phases.csv", f"{folder}/actions.csv")
        return something_else_demonstration(table[case["video"]])[0], 0
    from warpskill.synthetic import make_demonstration

    return make_demonstration(case["action"], seed=case["seed"], noise="moderate"), case["seed"]


def _warm_up(pipeline) -> None:
    """One short optimisation: the kernels loaded and Torch's one-off imports done outside the timing."""
    from warpskill.optimizer.config import OptimizeConfig
    from warpskill.synthetic import make_demonstration

    demo = make_demonstration("pick_up", seed=0, noise="moderate")
    pipeline.optimize(demo, progress=False, config=OptimizeConfig(iterations=2, init_iterations=2))


def main() -> None:
    """Time the cases read from stdin with the code of the checkout first on ``PYTHONPATH`` (or, given
    arguments, run its ``warpskill`` command line with them and exit with its status)."""
    _own_kernels(Path(os.environ["PYTHONPATH"].split(os.pathsep)[0]))
    if len(sys.argv) > 1:
        from warpskill.cli import main as command_line

        sys.exit(command_line(sys.argv[1:]))
    import warpskill.optimizer.pipeline as pipeline

    torch.set_num_threads(1)
    wp.launch = _counting_launch(wp.launch)
    pipeline.minimise = _timed_minimise(pipeline.minimise)
    _warm_up(pipeline)
    for line in sys.stdin:
        case = json.loads(line)
        demo, seed = demonstration(case)
        _stages.clear()
        start, cpu = time.perf_counter(), time.process_time()
        pipeline.optimize(demo, progress=False, seed=seed)
        seconds, cpu_seconds = time.perf_counter() - start, time.process_time() - cpu
        print(json.dumps({"case": case, "seconds": seconds, "cpu_seconds": cpu_seconds, "stages": dict(_stages),
                          "code": str(Path(pipeline.__file__).parents[2]),
                          "kernels": str(Path(sys.modules["warpskill.kernels"].__file__).parent)}), flush=True)


if __name__ == "__main__":
    main()
