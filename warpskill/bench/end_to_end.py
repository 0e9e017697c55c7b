"""The robot step of the end-to-end benchmarks: a reconstruction -> a Panda plan -> its replays.

:func:`robot_step` is what ``warpskill bench robot`` (synthetic reconstructions) and
``warpskill bench something-else --robot`` (real videos' reconstructions) do per case:
retarget the reconstruction (:func:`warpskill.robot.retarget`), replay the plan in each
engine (:func:`warpskill.robot.replay`) and judge the replayed object by the paper's
criteria, optionally once more under each perturbation a real robot meets (the *robust*
verdict); ``warpskill bench generalize`` does the same for a skill in a new layout. With a
folder it keeps ``plan.npz``, ``replay_<engine>.npz`` and (``video``)
the replay video of the first engine's scene (``replay.mp4``, or ``replay.png`` without an
offscreen renderer). :func:`robot_rows`, :func:`agreement` and :func:`timing_lines`
summarise a benchmark's outcomes the same way for both.
"""

from __future__ import annotations

import dataclasses
import statistics
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from warpskill.bench.outcomes import RobotRecord, one_line, verdict
from warpskill.contract.results_folder import ResultsFolder
from warpskill.contract.skill import LayoutError
from warpskill.robot import PlanError, prefer_headless_gl, record, replay, retarget
from warpskill.robot.perturbation import PERTURBATIONS

ENGINES: tuple[str, ...] = ("mujoco", "newton")


@dataclasses.dataclass
class RobotOutcome:
    """What the robot did with one reconstruction.

    Attributes:
        plan: the plan, or None when none was found.
        reason: why no plan was found (one line), else None.
        replays: engine -> :class:`~warpskill.contract.replay.Replay`, in the order run.
        video: the replay video (or plot) written, else None.
        cpu_seconds: engine -> CPU time [s] of this process during the replay (the replay's
            ``replay_time`` is wall-clock time, which other work on the machine stretches).
        perturbed: perturbation name -> whether the MuJoCo replay under it succeeded
            (:data:`~warpskill.robot.perturbation.PERTURBATIONS`); empty when not tried.
    """

    plan: object | None = None
    reason: str | None = None
    replays: dict = dataclasses.field(default_factory=dict)
    video: Path | None = None
    cpu_seconds: dict = dataclasses.field(default_factory=dict)
    perturbed: dict = dataclasses.field(default_factory=dict)

    @property
    def planned(self) -> bool:
        return self.plan is not None

    def success(self, engine: str) -> bool:
        """Whether the replay in ``engine`` achieved the action (False without a plan)."""
        result = self.replays.get(engine)
        return bool(result is not None and result.success)

    @property
    def replayed(self) -> bool:
        """Whether a plan was found and its replay achieved the action in every engine run."""
        return self.planned and bool(self.replays) and all(result.success for result in self.replays.values())

    @property
    def robust(self) -> bool:
        """Whether the plan succeeded in every engine run and in MuJoCo under every perturbation tried."""
        return self.replayed and bool(self.perturbed) and all(self.perturbed.values())

    @property
    def handling(self) -> str:
        """How the plan holds the object: ``"substituted"`` (a cuboid the gripper fits instead of
        one too wide for every face and rim), ``"held by its rim"`` (an open vessel), or ``""``
        (as it is, or no plan): from the plan's note (:func:`~warpskill.robot.sizes.fit_sizes`)."""
        note = self.plan.note if self.planned else ""
        return "substituted" if "substitute" in note else "held by its rim" if "rim" in note else ""

    def broken_by(self) -> list[str]:
        """Names of the perturbations under which the MuJoCo replay failed."""
        return [name for name, ok in self.perturbed.items() if not ok]

    def misses(self) -> list[str]:
        """Why the case missed, one line each: the plan's error, each engine's failed checks,
        the perturbations that broke it (empty: it succeeded everywhere it was tried)."""
        if not self.planned:
            return [f"plan: {self.reason}"]
        lines = [f"{engine} replay fails {', '.join(self.failed_checks(engine))}"
                 for engine, result in self.replays.items() if not result.success]
        broken = self.broken_by()
        return lines + ([f"not robust: fails under {', '.join(broken)}"] if broken else [])

    def record(self) -> RobotRecord:
        """The outcome as the outcome table keeps it (``CaseOutcome.robot``)."""
        return RobotRecord(self.planned, {engine: self.success(engine) for engine in self.replays},
                           self.robust if self.perturbed else None, tuple(self.misses()),
                           self.plan.note if self.handling == "substituted" else "")

    def agree(self) -> bool:
        """Whether every engine run gives the same verdict."""
        return len({result.success for result in self.replays.values()}) <= 1

    def end_difference(self) -> float | None:
        """The largest distance [m] between two engines' final object positions (None with fewer than two)."""
        ends = [result.reconstruction.object_pos[-1] for result in self.replays.values()]
        if len(ends) < 2:
            return None
        return max(float(np.linalg.norm(a - b)) for i, a in enumerate(ends) for b in ends[i + 1:])

    def failed_checks(self, engine: str) -> list[str]:
        result = self.replays.get(engine)
        return [] if result is None else [name for name, ok in result.evaluation.checks.items() if not ok]

    def summary(self) -> str:
        """One line: the plan (or why none) and each engine's verdict and time."""
        if not self.planned:
            return f"no plan ({self.reason})"
        plan = self.plan
        where = "" if plan.offset is None else (f", at ({plan.offset[0]:.2f}, {plan.offset[1]:.2f}) m "
                                                f"{np.degrees(plan.yaw):.0f} deg")
        resized = f", object {self.handling}" if self.handling else ""
        verdicts = [f"{engine} {verdict(result.success)} {result.replay_time:5.1f} s"
                    for engine, result in self.replays.items()]
        return (f"planned {plan.planning_time:4.1f} s ({plan.grasp_name}{where}{resized}); " + "; ".join(verdicts))


def check_robust_engines(engines: Sequence[str]) -> None:
    """Refuse robust replays without MuJoCo (ValueError): the perturbations edit its model."""
    if "mujoco" not in engines:
        raise ValueError("robust replays need the mujoco engine (the perturbations edit its model): "
                         "add mujoco to the engines, or skip the robust row (--no-robust)")


def robot_step(recon, folder: Path | None = None, *, engines: Sequence[str] = ENGINES, device: str = "cpu",
               video: bool = False, robust: bool = False, skill=None, layout=None) -> RobotOutcome:
    """Retarget ``recon`` to the Panda and replay the plan in each of ``engines``.

    Args:
        recon: the reconstruction (its ``action`` is the one judged); with ``layout``, the
            layout's scene (``apply_skill(skill, layout)``) that the replays are judged on.
        folder: where to keep ``plan.npz``, ``replay_<engine>.npz`` and the video (None: nothing written).
        engines: replay engines, in order (``mujoco``, ``newton``).
        device: Warp device of the Newton replay.
        video: also write the replay video into ``folder`` (MuJoCo's rendering of the plan).
        robust: where the plan succeeds in every engine, replay it in MuJoCo once more under
            each of :data:`~warpskill.robot.perturbation.PERTURBATIONS` (needs ``mujoco``
            among ``engines``: the perturbations edit its model).
        skill, layout: plan ``skill`` in ``layout`` (:func:`warpskill.robot.retarget`)
            instead of ``recon`` as demonstrated.

    Returns:
        The :class:`RobotOutcome`; a plan that cannot be made is an outcome with its reason
        (:class:`~warpskill.robot.PlanError`, :class:`~warpskill.contract.skill.LayoutError`),
        not an exception.
    """

    if robust:
        check_robust_engines(engines)
    prefer_headless_gl()  # before MuJoCo is first imported (a no-op afterwards)
    try:
        plan = retarget(recon if skill is None else skill, layout=layout)
    except (PlanError, LayoutError) as error:
        return RobotOutcome(reason=one_line(error))
    outcome = RobotOutcome(plan=plan)
    if folder is not None:
        keeper = ResultsFolder(folder)
        keeper.save(plan, keeper.plan)
    for engine in engines:
        cpu = time.process_time()
        result = replay(plan, recon, engine=engine, device=None if engine == "mujoco" else device)
        outcome.cpu_seconds[engine] = time.process_time() - cpu
        outcome.replays[engine] = result
        if folder is not None:
            keeper.save(result, keeper.engine_replay(engine))
    if robust and outcome.replayed:
        outcome.perturbed = {p.name: replay(plan, recon, edit_model=p).success for p in PERTURBATIONS}
    if video and folder is not None and outcome.replays:
        outcome.video = record(plan, plan.scene(recon), next(iter(outcome.replays.values())), folder)
    return outcome


def robot_rows(cases: Sequence[tuple[str, bool, RobotOutcome | None]], engines: Sequence[str], *,
               reconstruction_row: str = "reconstruction", robust: bool = False) -> dict[str, list]:
    """The end-to-end success table's rows, as (action, ok) pairs per case.

    Rows: ``reconstruction_row`` (the reconstruction meets the criteria), ``planned``,
    ``replay <engine>`` (the replayed object meets them), ``robust`` (with ``robust``: the
    replay succeeds in every engine and under every perturbation, :attr:`RobotOutcome.robust`)
    and ``end to end`` (the reconstruction and the replay in every engine do).

    Args:
        cases: (action, reconstruction ok, outcome) per case; an outcome of None (no
            reconstruction, or the robot step not run) fails the robot rows.
    """
    rows: dict[str, list] = {reconstruction_row: [], "planned": [], **{f"replay {engine}": [] for engine in engines},
                             **({"robust": []} if robust else {}), "end to end": []}
    for action, reconstructed, outcome in cases:
        rows[reconstruction_row].append((action, bool(reconstructed)))
        rows["planned"].append((action, outcome is not None and outcome.planned))
        for engine in engines:
            rows[f"replay {engine}"].append((action, outcome is not None and outcome.success(engine)))
        if robust:
            rows["robust"].append((action, outcome is not None and outcome.robust))
        rows["end to end"].append((action, bool(reconstructed) and outcome is not None and outcome.replayed))
    return rows


def agreement(outcomes: Sequence[RobotOutcome | None]) -> dict:
    """How the engines agree over the replayed cases.

    Returns:
        ``{"cases": n replayed in two or more engines, "agree": same verdict, "disagree":
        [index], "max_end_difference": m or None}`` (indices into ``outcomes``).
    """
    both = [(i, o) for i, o in enumerate(outcomes) if o is not None and len(o.replays) >= 2]
    differences = [o.end_difference() for _, o in both]
    return {
        "cases": len(both),
        "agree": sum(o.agree() for _, o in both),
        "disagree": [i for i, o in both if not o.agree()],
        "max_end_difference": max(differences) if differences else None,
    }


def agreement_line(outcomes: Sequence[RobotOutcome | None]) -> str | None:
    """``engines agree on k/n replayed cases; object end positions within d m`` (None without two engines)."""
    summary = agreement(outcomes)
    if not summary["cases"]:
        return None
    return (f"engines agree on {summary['agree']}/{summary['cases']} replayed case(s); final object positions "
            f"differ by at most {summary['max_end_difference']:.3f} m")


def timing_lines(outcomes: Sequence[RobotOutcome | None]) -> list[str]:
    """Median and max planning time and replay time per engine."""
    planned = [o for o in outcomes if o is not None and o.planned]
    lines = []
    planning = [o.plan.planning_time for o in planned]
    if planning:
        lines.append(f"planning time per plan: median {statistics.median(planning):.2f} s, max {max(planning):.2f} s")
    engines = list(dict.fromkeys(engine for o in planned for engine in o.replays))
    for engine in engines:
        seconds = [o.replays[engine].replay_time for o in planned if engine in o.replays]
        cpu = [o.cpu_seconds[engine] for o in planned if engine in o.cpu_seconds]
        line = f"{engine} replay time per plan: median {statistics.median(seconds):.2f} s, max {max(seconds):.2f} s"
        if cpu:
            line += f" (CPU time: median {statistics.median(cpu):.2f} s, max {max(cpu):.2f} s)"
        lines.append(line)
    return lines
