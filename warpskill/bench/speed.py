"""``warpskill bench speed``: the Warp engine against its plain-Torch reference, side by side.

One synthetic put_onto demonstration (50 frames, 240 x 427 masks, hand + object + one
static cuboid) is set up as :func:`warpskill.optimize` sets it up, and each optimisation
stage's iteration (objective forward + backward) is timed with either engine underneath:

- ``warp``: :func:`warpskill.engine.simulation.simulate` and :func:`warpskill.engine.rendering.render_silhouettes`;
- ``reference``: :func:`warpskill.engine.reference.simulate_reference` and
  :func:`warpskill.engine.reference.render_reference` (the "original approach": plain PyTorch);
- ``dopri5``: :func:`warpskill.engine.reference.simulate_dopri5` (the paper's integrator: adaptive
  dopri5 with grasp/release events, float64, ``torchdiffeq`` from the ``baselines`` extra)
  for the physics stage's rollout only; rendering stays Warp's, so stage (a), which has no
  physics, runs as ``warp`` and stage (b) differs from ``warp`` by the rollout alone.

A full optimisation is estimated from the iteration times and the default iteration
counts (both depth hypotheses of stage (a), then stage (b); an upper bound, since the
plateau schedule may stop stage (b) early) or, with ``measure_full``, timed by running
:func:`warpskill.optimize` on each engine.
"""

from __future__ import annotations

import copy
import json
import os
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import torch

from warpskill.bench.report import show
from warpskill.bench.settings import DEV_DATA_VARIABLE, data_folder
from warpskill.bench.timing import timed
from warpskill.contract.actions import ACTIONS
from warpskill.contract.demonstration import Demonstration
from warpskill.contract.evaluation import evaluate
from warpskill.engine.device import resolve_device
from warpskill.engine.reference.dopri5 import simulate_dopri5
from warpskill.engine.reference.physics import simulate_reference
from warpskill.engine.reference.raster import render_reference
from warpskill.optimizer.batching import Backend, render_many, simulate_many
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.guess import ObjectDepth, initial_guess
from warpskill.optimizer.inputs import WorkingInputs, working_inputs
from warpskill.optimizer.pipeline import optimize, optimize_many
from warpskill.optimizer.scene import SceneTrajectories
from warpskill.optimizer.stage_a import InitialParameters, initial_objective
from warpskill.optimizer.stage_b import (
    PhysicalScene,
    make_physical_scene,
    physical_objective,
)
from warpskill.synthetic import make_demonstration

ENGINES = ("warp", "reference", "dopri5")
DEFAULT_ENGINES = ("warp", "reference")  # dopri5's stage (b) iteration takes seconds
FPS = 12.0


def backend(name: str) -> Backend:
    """The engine ``name`` (one of :data:`ENGINES`) as the optimiser's :class:`~warpskill.optimizer.batching.Backend`.

    ``reference`` is the plain-Torch rollout and renderer; ``dopri5`` the dopri5 rollout
    with Warp's renderer; ``warp`` the Warp engine.
    """
    if name not in ENGINES:
        raise ValueError(f"engine must be one of {ENGINES}, got {name!r}")
    if name == "reference":
        return Backend(name, simulate_reference, render_reference, profile=None)
    if name == "dopri5":
        if simulate_dopri5 is None:
            raise ValueError("engine 'dopri5' needs torchdiffeq: pip install 'warpskill[baselines]'")
        return Backend(name, simulate=simulate_dopri5)
    return Backend()


@dataclass
class Problem:
    """Both optimisation stages of one demonstration, ready to iterate.

    Attributes:
        demo: the demonstration.
        config: the optimisation settings.
        inputs: the masks and contact at the working resolution.
        initial: stage (a) parameters (the first depth hypothesis's initial guess).
        physical: stage (b) parameters, started from the demonstration's ground truth.
    """

    demo: Demonstration
    config: OptimizeConfig
    inputs: WorkingInputs
    initial: InitialParameters
    physical: PhysicalScene

    def stage_a(self, engine: Backend) -> dict[str, torch.Tensor]:
        """Stage (a) loss terms of :attr:`initial` on ``engine``."""
        scene = self.initial.scene()
        [rendered] = render_many([scene], [self.inputs.intrinsics], self.config.sigma, engine, [self.inputs.targets])
        return initial_objective(scene, rendered, self.inputs.targets, self.inputs.contact, self.demo.fps,
                                 self.config.weights)

    def stage_b(self, engine: Backend, scenes: Sequence[PhysicalScene] | None = None) -> dict[str, torch.Tensor]:
        """Stage (b) loss terms of :attr:`physical` (or of ``scenes`` fitting the same masks, summed)
        on ``engine``, with the batched calls of :func:`warpskill.optimize_many`."""
        scenes = list(scenes or [self.physical])
        rollouts = simulate_many([scene.simulation_inputs() for scene in scenes],
                                 [scene.simulation_options() for scene in scenes], engine.simulate)
        results = [scene.assemble(rollout) for scene, rollout in zip(scenes, rollouts)]
        given = self.inputs
        rendered = render_many([r.scene for r in results], [given.intrinsics] * len(scenes), self.config.sigma,
                               engine, [given.targets] * len(scenes))
        terms = [physical_objective(r, masks, given.targets, given.contact, given.object_visible, self.config.weights)
                 for r, masks in zip(results, rendered)]
        return {name: sum(t[name] for t in terms) for name in terms[0]}


def make_problem(
    *, frames: int = 50, image_size: tuple[int, int] = (240, 427), image_scale: float = 0.25, device="cpu"
) -> Problem:
    """A put_onto demonstration of ``frames`` frames at ``image_size`` [px], with its stage
    objectives at ``image_scale`` of that resolution, as :func:`warpskill.optimize` builds them."""
    if frames < 4:
        raise ValueError(f"frames must be >= 4, got {frames}")
    device = resolve_device(device)
    config = OptimizeConfig(image_scale=image_scale)
    demo = make_demonstration("put_onto", image_size=image_size, duration=(frames - 1) / FPS, fps=FPS)
    inputs = working_inputs(demo, config, device)
    guess = initial_guess(inputs.masks.cpu().numpy(), inputs.contact_signal, inputs.intrinsics, demo.num_static)
    truth = SceneTrajectories(
        **{k: torch.as_tensor(demo.truth[k], dtype=torch.float32) for k in SceneTrajectories.__dataclass_fields__}
    )
    return Problem(
        demo=demo,
        config=config,
        inputs=inputs,
        initial=InitialParameters(guess).to(device),
        physical=make_physical_scene(truth, inputs.contact_signal, demo.fps, config).to(device),
    )


def iteration(objective: Callable[[], dict[str, torch.Tensor]], *modules: torch.nn.Module) -> Callable[[], float]:
    """One optimisation iteration's work: the loss terms' sum and its backward pass (the
    gradients of ``modules`` cleared first)."""

    def run() -> float:
        for module in modules:
            module.zero_grad(set_to_none=True)
        loss = sum(objective().values())
        loss.backward()
        return loss.item()

    return run


def median_seconds(fn: Callable[[], object], repeats: int, device: torch.device) -> float:
    """Median wall time [s] of ``repeats`` calls of ``fn`` after one warm-up call."""
    return timed(fn, max(1, repeats), device)[1]


def bench_speed(
    *,
    devices: Sequence[str] = ("cpu",),
    engines: Sequence[str] = DEFAULT_ENGINES,
    repeats: int = 3,
    measure_full: bool = False,
    scaling: bool = False,
) -> list[dict]:
    """Time both optimisation stages' iterations per engine and device; print one table.

    Args:
        devices: torch devices to run on (``"cpu"``, ``"cuda"``).
        engines: a subset of :data:`ENGINES`.
        repeats: timed iterations per measurement (median reported).
        measure_full: also run :func:`warpskill.optimize` end to end per engine and device
            (minutes for the reference).
        scaling: also print stage (b) iteration times as frames, image size and the
            number of scenes B grow (:func:`bench_scaling`).

    Returns:
        The rows of the table: engine, device, per-iteration seconds of both stages,
        full-optimisation seconds (estimated, and measured when asked).
    """
    for name in engines:
        if name not in ENGINES:
            raise ValueError(f"engine must be one of {ENGINES}, got {name!r}")
    rows = []
    for device in map(resolve_device, devices):
        problem = make_problem(device=device)
        config = problem.config
        for name in engines:
            engine = backend(name)
            stage_a = median_seconds(iteration(lambda: problem.stage_a(engine), problem.initial), repeats, device)
            stage_b = median_seconds(iteration(lambda: problem.stage_b(engine), problem.physical), repeats, device)
            estimate = len(ObjectDepth) * config.init_iterations * stage_a + config.iterations * stage_b
            measured = None
            if measure_full:
                start = time.perf_counter()
                optimize(problem.demo, device=device, progress=False, backend=engine)
                measured = time.perf_counter() - start
            rows.append(dict(engine=name, device=str(device), stage_a_s=stage_a, stage_b_s=stage_b,
                             full_estimate_s=estimate, full_measured_s=measured))
    _print_table(rows, problem, repeats)
    if scaling:
        bench_scaling(devices=devices, engines=engines, repeats=repeats)
    return rows


def _print_table(rows: list[dict], problem: Problem, repeats: int) -> None:
    demo, config = problem.demo, problem.config
    h, w = demo.intrinsics.scaled(config.image_scale).image_size
    show(
        f"one iteration = objective forward + backward; {demo.num_frames} frames of {demo.image_size[0]} x "
        f"{demo.image_size[1]} masks, rendered at {h} x {w}; median of {repeats}; torch threads "
        f"{torch.get_num_threads()}"
    )
    show(
        f"full optimisation = {len(ObjectDepth)} x {config.init_iterations} stage (a) + "
        f"{config.iterations} stage (b) iterations (an upper bound); 'measured' runs warpskill.optimize"
    )
    warp = {r["device"]: r for r in rows if r["engine"] == "warp"}
    header = (
        f"{'engine':<10} {'device':<7} {'(a) iter [ms]':>13} {'(b) iter [ms]':>13} {'full est. [s]':>13} "
        f"{'measured [s]':>12} {'x warp (a)':>10} {'x warp (b)':>10} {'x warp full':>11}"
    )
    show(header)
    for r in rows:
        base = warp.get(r["device"])
        ratio = lambda key: f"{r[key] / base[key]:.1f}" if base and r[key] else "-"  # noqa: E731
        measured = f"{r['full_measured_s']:.1f}" if r["full_measured_s"] is not None else "-"
        show(
            f"{r['engine']:<10} {r['device']:<7} {1e3 * r['stage_a_s']:>13.1f} {1e3 * r['stage_b_s']:>13.1f} "
            f"{r['full_estimate_s']:>13.1f} {measured:>12} {ratio('stage_a_s'):>10} {ratio('stage_b_s'):>10} "
            f"{ratio('full_measured_s' if r['full_measured_s'] else 'full_estimate_s'):>11}"
        )


def bench_scaling(
    *,
    devices: Sequence[str] = ("cpu",),
    engines: Sequence[str] = DEFAULT_ENGINES,
    repeats: int = 3,
    frames: Sequence[int] = (25, 50, 100),
    scales: Sequence[float] = (0.125, 0.25, 0.5),
    batches: Sequence[int] = (1, 4, 16),
) -> list[dict]:
    """Stage (b) iteration time [ms] as the frames, the working image size and the batch grow.

    Frames and image size vary one at a time about the default problem (50 frames, 240 x
    427 masks at scale 0.25). A batch of B is one iteration of :func:`warpskill.optimize_many`
    over B scenes: one rollout of all of them and one rendering of their B x 50 frames.
    Prints a table and returns its rows.
    """
    rows = []
    for device in map(resolve_device, devices):
        cases: list[tuple[str, Callable[[], Problem]]] = [
            *((f"frames {n}", lambda n=n: make_problem(frames=n, device=device)) for n in frames),
            *((f"scale {s}", lambda s=s: make_problem(image_scale=s, device=device)) for s in scales),
        ]
        for label, build in cases:
            problem = build()
            h, w = problem.demo.intrinsics.scaled(problem.config.image_scale).image_size
            row = dict(case=label, device=str(device), frames=problem.demo.num_frames, image=f"{h}x{w}", batch=1)
            for name in engines:
                engine = backend(name)
                row[name] = median_seconds(iteration(lambda: problem.stage_b(engine), problem.physical), repeats,
                                           device)
            rows.append(row)
        problem = make_problem(device=device)
        h, w = problem.inputs.intrinsics.image_size
        for batch in batches:
            row = dict(case=f"batch {batch}", device=str(device), frames=50, image=f"{h}x{w}", batch=batch)
            scenes = [copy.deepcopy(problem.physical) for _ in range(batch)]
            for name in engines:
                engine = backend(name)
                row[name] = median_seconds(
                    iteration(lambda: problem.stage_b(engine, scenes), *scenes), repeats, device)
            rows.append(row)
    show(f"stage (b) iteration [ms] (median of {repeats})")
    show(f"{'case':<12} {'device':<7} {'frames':>6} {'image':>8} {'B':>3} " + " ".join(f"{n:>10}" for n in engines)
          + (f" {'ratio':>7}" if len(engines) > 1 else ""))
    for r in rows:
        times = " ".join(f"{1e3 * r[n]:>10.1f}" for n in engines)
        ratio = f" {r[engines[-1]] / r[engines[0]]:>7.1f}" if len(engines) > 1 else ""
        show(f"{r['case']:<12} {r['device']:<7} {r['frames']:>6} {r['image']:>8} {r['batch']:>3} {times}{ratio}")
    return rows


def bench_many(*, batches: Sequence[int] = (1, 8), devices: Sequence[str] = ("cpu",)) -> list[dict]:
    """Demonstrations per second of :func:`warpskill.optimize_many` with the default settings.

    A batch of B is B synthetic demonstrations (the 9 actions in turn, 50 frames of 240 x
    427, moderate noise), both stages, optimised together. Prints a table and returns its rows.
    """

    rows = []
    for device in map(resolve_device, devices):
        for batch in batches:
            demos = [make_demonstration(ACTIONS[i % len(ACTIONS)], seed=i // len(ACTIONS), fps=FPS,
                                        duration=49 / FPS) for i in range(batch)]
            start = time.perf_counter()
            reconstructions = optimize_many(demos, device=device, progress=False)
            seconds = time.perf_counter() - start
            succeeded = sum(evaluate(r, d.action).success for r, d in zip(reconstructions, demos))
            rows.append(dict(device=str(device), batch=batch, seconds=seconds, rate=batch / seconds,
                             succeeded=succeeded))
    show("warpskill.optimize_many, default settings, both stages")
    show(f"{'device':<7} {'B':>4} {'total [s]':>10} {'demos/s':>8} {'succeeded':>10}")
    for r in rows:
        show(f"{r['device']:<7} {r['batch']:>4} {r['seconds']:>10.1f} {r['rate']:>8.3f} {r['succeeded']:>6}/{r['batch']}")
    return rows


SETS = ("dev", "synthetic")


def speed_cases(name: str, *, folder: str | os.PathLike | None = None, seeds: int = 1,
                videos: Sequence[str] = ()) -> list[dict]:
    """The cases of set ``name`` (:data:`SETS`): the development videos in ``folder`` (None:
    ``$WARPSKILL_DEV_DATA``; or ``videos`` of them), or the 9 actions x ``seeds`` synthetic
    demonstrations (moderate noise).

    Raises:
        SettingError: the dev set without a folder.
    """
    if name not in SETS:
        raise ValueError(f"set must be one of {SETS}, got {name!r}")
    if name == "synthetic":
        return [{"set": name, "action": a, "seed": s} for a in ACTIONS for s in range(seeds)]
    from warpskill.data.boxes.something_else import read_something_else

    folder = str(data_folder(folder, DEV_DATA_VARIABLE, "--folder", "folder of the development videos").resolve())
    table = read_something_else(f"{folder}/annotations.json", f"{folder}/phases.csv", f"{folder}/actions.csv")
    return [{"set": name, "video": v, "folder": folder} for v in (videos or table)]


class _Worker:
    """A :mod:`warpskill.bench.stage_timing` process timing the checkout at ``root`` (one thread)."""

    def __init__(self, root: Path):
        env = dict(os.environ, PYTHONPATH=str(root), OMP_NUM_THREADS="1")
        self.process = subprocess.Popen([sys.executable, str(Path(__file__).with_name("stage_timing.py"))],
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env, cwd=root)

    def time(self, case: dict) -> dict:
        self.process.stdin.write(json.dumps(case) + "\n")
        self.process.stdin.flush()
        line = self.process.stdout.readline()
        if not line:
            raise RuntimeError(f"the timing worker stopped (exit {self.process.wait()}) on {case}")
        return json.loads(line)

    def close(self) -> None:
        self.process.stdin.close()
        self.process.wait()


def bench_speed_set(name: str, *, against: str | None = None, baseline: str | None = None, out: str | None = None,
                    folder: str | os.PathLike | None = None, seeds: int = 1, videos: Sequence[str] = ()) -> dict:
    """Per-stage speed of :func:`warpskill.optimize` over a set, one case after another on one core.

    Args:
        name: ``"dev"`` or ``"synthetic"`` (:func:`speed_cases`).
        against: a checkout of the previous release (e.g. a git worktree of the previous commit),
            timed in the same run, case by case alternating which goes first.
        baseline: a JSON file this command wrote before (``out``), shown beside instead.
        out: write this run's figures here (JSON), to be a later run's ``baseline``.
        folder, seeds, videos: which cases (:func:`speed_cases`).

    Returns:
        ``{"this": [...], "previous": [...] or None}``, one worker record per case.
    """
    cases = speed_cases(name, folder=folder, seeds=seeds, videos=videos)
    roots = {"this": Path(__file__).resolve().parents[2]} | ({"previous": Path(against).resolve()} if against else {})
    workers = {label: _Worker(root) for label, root in roots.items()}
    results: dict = {label: [] for label in workers}
    try:
        for i, case in enumerate(cases):
            for label in sorted(workers, reverse=i % 2 == 1):
                results[label].append(workers[label].time(case))
    finally:
        for worker in workers.values():
            worker.close()
    if baseline and not against:
        results["previous"] = json.loads(Path(baseline).read_text())["this"]
    if out:
        Path(out).write_text(json.dumps(results, indent=1))
    _print_set_table(name, results)
    return results


def stage_figures(records: Sequence[dict], clock: str = "cpu_seconds") -> dict[str, dict[str, float]]:
    """Per stage over the cases: ms per iteration (total time over total iterations), and the median
    per case of iterations and launches; ``"video"``: the median and range of seconds per case. Times
    by ``clock``: ``"cpu_seconds"`` (the process's CPU time) or ``"seconds"`` (wall)."""
    figures = {}
    for stage in sorted({s for r in records for s in r["stages"]}):
        rows = [r["stages"][stage] for r in records if stage in r["stages"]]
        per_iteration = sum(r[clock] for r in rows) / max(1, sum(r["iterations"] for r in rows))
        figures[stage] = {"ms_per_iteration": 1e3 * per_iteration,
                          "iterations": statistics.median(r["iterations"] for r in rows),
                          "launches": statistics.median(r["launches"] for r in rows)}
    seconds = [r[clock] for r in records]
    figures["video"] = {"median_s": statistics.median(seconds), "min_s": min(seconds), "max_s": max(seconds)}
    return figures


def _print_set_table(name: str, results: dict) -> None:
    now, before = stage_figures(results["this"]), results.get("previous") and stage_figures(results["previous"])
    show(f"set {name}: {len(results['this'])} cases, one after another, one thread each"
          + ("; previous release beside" if before else "") + "; CPU time of the process")
    show(f"{'stage':<16} {'ms/iteration':>14} {'iterations':>14} {'launches':>16}  (this / previous; median per case)")
    for stage in (s for s in now if s != "video"):
        old = (before or {}).get(stage)
        pair = lambda key, fmt: f"{now[stage][key]:{fmt}}" + (f" / {old[key]:{fmt}}" if old else "")  # noqa: E731
        show(f"{stage:<16} {pair('ms_per_iteration', '.1f'):>14} {pair('iterations', '.0f'):>14} "
              f"{pair('launches', '.0f'):>16}")
    for label, records in results.items():
        for clock in ("cpu_seconds", "seconds"):
            video = stage_figures(records, clock)["video"]
            kind = "CPU" if clock == "cpu_seconds" else "wall"
            show(f"per case ({label}, {kind}): median {video['median_s']:.1f} s "
                  f"({video['min_s']:.1f}-{video['max_s']:.1f} s)")
