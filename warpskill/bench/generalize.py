"""``warpskill bench generalize``: does a skill work beyond the one layout it was shown in?

For each reconstruction's skill (:func:`~warpskill.contract.skill.skill_from`), ``layouts``
random layouts of :func:`warpskill.export.layouts.layouts` (the object anywhere on the
Panda's reachable table at any yaw; each static box at a random place and yaw there, apart
from the object, with the object's whole path on the table), each planned
(:func:`warpskill.robot.retarget` with the layout) and replayed in every engine, judged by
the action's criteria on the layout's scene. A plan that succeeds in MuJoCo is replayed once
more under each of :data:`~warpskill.export.perturbation.PERTURBATIONS` (mass x0.5 and x2,
friction -+30 %, the object 1 cm and 5 deg off); it is *robust* when it succeeds under all.

Prints, per action, planned / succeeded (per engine) / robust as a success table, and the
reason of every miss (the plan's error, the failed checks, the perturbations that broke it).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from itertools import islice

from warpskill.contract.evaluation import success_table
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.skill import LayoutError, skill_from
from warpskill.export.layouts import layouts as random_layouts
from warpskill.export.perturbation import PERTURBATIONS
from warpskill.robot import PlanError, prefer_headless_gl, replay, retarget

__all__ = ["bench_generalize", "robust_misses"]


def robust_misses(plan, recon) -> list[str]:
    """Names of the perturbations under which the MuJoCo replay of ``plan`` fails (empty: robust)."""

    return [p.name for p in PERTURBATIONS if not replay(plan, recon, edit_model=p).success]


def _case(skill, layout, engines: Sequence[str], device: str, robust: bool) -> tuple[dict[str, bool], list[str]]:
    """One layout: ``{"planned", "replay <engine>"..., "robust"}`` verdicts and the reasons of its misses."""

    verdicts = {"planned": False, **{f"replay {engine}": False for engine in engines}, "robust": False}
    recon = skill.apply(layout)
    try:
        plan = retarget(skill, layout=layout)
    except (PlanError, LayoutError) as error:
        return verdicts, [f"plan: {error}"]
    verdicts["planned"], reasons = True, []
    for engine in engines:
        result = replay(plan, recon, engine, device=device)
        verdicts[f"replay {engine}"] = result.success
        if not result.success:
            reasons.append(f"{engine} fails {', '.join(k for k, ok in result.evaluation.checks.items() if not ok)}")
    if robust and verdicts.get("replay mujoco", False):
        broken = robust_misses(plan, recon)
        verdicts["robust"] = not broken
        reasons += [f"not robust: fails under {', '.join(broken)}"] if broken else []
    return verdicts, reasons


def _count(rows: dict, action: str, verdicts: dict[str, bool], robust: bool) -> None:
    """Add one layout's verdicts to the table's rows (the robust row only where computed)."""
    for row, ok in verdicts.items():
        if row != "robust" or robust:
            rows.setdefault(row, []).append((action, ok))


def bench_generalize(recons: Mapping[str, Reconstruction], *, layouts: int = 10,
                     engines: Sequence[str] = ("mujoco",), seed: int = 0, device: str = "cpu",
                     robust: bool = True) -> dict:
    """Plan and replay every skill in ``layouts`` random layouts; print the table and the misses.

    Args:
        recons: name -> reconstruction (each with a known action).
        layouts: random layouts per skill.
        engines: replay engines (``mujoco``, ``newton``).
        seed: of the layouts (the i-th reconstruction draws from ``seed + i``).
        device: Warp device of Newton.
        robust: also replay each MuJoCo success under the perturbations (``robust`` row;
            needs ``mujoco`` among the engines).

    Returns:
        ``{"rows": {row: [(action, ok)]}, "misses": [str]}``, rows ``planned``,
        ``replay <engine>``, and ``robust`` when computed.
    """

    prefer_headless_gl()
    robust = robust and "mujoco" in engines
    rows: dict[str, list[tuple[str, bool]]] = {}
    misses = []
    for i, (name, recon) in enumerate(recons.items()):
        skill, done = skill_from(recon), 0
        try:
            for k, layout in enumerate(islice(random_layouts(skill, seed=seed + i), layouts)):
                verdicts, reasons = _case(skill, layout, engines, device, robust)
                done += 1
                _count(rows, skill.action, verdicts, robust)
                misses += [f"{name} layout {k} ({layout.describe()}): {reason}" for reason in reasons]
                print(f"{name} layout {k}: " + ", ".join(f"{row} {'yes' if ok else 'no'}"
                                                         for row, ok in verdicts.items()), flush=True)
        except LayoutError as error:  # no layout fits this skill (e.g. its path runs into the static box)
            unplanned = {"planned": False, **{f"replay {engine}": False for engine in engines}, "robust": False}
            for _ in range(layouts - done):
                _count(rows, skill.action, unplanned, robust)
            misses.append(f"{name}: every layout: {error}")
            print(f"{name}: no layout: {error}", flush=True)
    print()
    print(success_table(rows))
    if misses:
        print("misses:")
        for line in misses:
            print(f"  {line}")
    return {"rows": rows, "misses": misses}
