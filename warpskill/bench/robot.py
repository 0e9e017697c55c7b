"""``warpskill bench robot``: retarget synthetic reconstructions to the Panda and replay them.

For each action and seed: the reconstruction (the synthetic ground truth, or the optimiser's
output on the noisy demonstration), a placo plan, and its replay in each engine, judged by
:func:`warpskill.evaluate`. Prints the success table per engine, the planning and replay
times, and the reason of every failed plan.
"""

from __future__ import annotations

import math
import statistics
from pathlib import Path
from typing import Sequence

from warpskill.contract.actions import ACTIONS

SOURCES: tuple[str, ...] = ("truth", "optimised")


def synthetic_reconstruction(action: str, seed: int, source: str, *, noise: str = "moderate",
                             folder: Path | None = None, device: str = "cpu"):
    """The reconstruction of synthetic ``action`` / ``seed`` from ``source``.

    ``truth``: the noise-free ground truth; ``optimised``: :func:`warpskill.optimize` on the
    demonstration with ``noise``, cached as ``folder/reconstruction.npz`` when ``folder`` is
    given (a rerun loads it).
    """
    from warpskill.contract.reconstruction import Reconstruction
    from warpskill.optimizer.pipeline import optimize
    from warpskill.synthetic import make_demonstration

    if source not in SOURCES:
        raise ValueError(f"unknown source {source!r}; valid sources: {', '.join(SOURCES)}")
    if source == "truth":
        return Reconstruction(**make_demonstration(action, seed=seed, noise="none").truth)
    cached = folder / "reconstruction.npz" if folder is not None else None
    if cached is not None and cached.is_file():
        return Reconstruction.load(cached)
    recon = optimize(make_demonstration(action, seed=seed, noise=noise), device=device, seed=seed, progress=False,
                     checkpoint=folder / "checkpoint.pt" if folder is not None else None)
    if cached is not None:
        recon.save(cached)
    return recon


def bench_robot(*, seeds: int = 3, source: str = "truth", engines: Sequence[str] = ("mujoco",),
                actions: Sequence[str] | None = None, out: Path | None = None, device: str = "cpu",
                video: bool = False) -> dict:
    """Plan and replay every action x seed; print the success table per engine and the timings.

    Args:
        seeds: seeds per action.
        source: ``truth`` or ``optimised`` (see :func:`synthetic_reconstruction`).
        engines: replay engines (``mujoco``, ``newton``).
        actions: a subset of the actions (default: all 9).
        out: folder for the reconstructions and plans (``OUT/<action>_<seed>/``); optimised
            reconstructions found there are reused.
        device: Torch device of the optimiser and Warp device of Newton.
        video: also write ``OUT/<action>_<seed>/replay.mp4`` of each plan (MuJoCo; a plot
            without an offscreen renderer).

    Returns:
        ``{"rows": {row: [(action, ok)]}, "planning": [s], "replay": {engine: [s]}, "failures": [str]}``.
    """
    from warpskill.contract.evaluation import success_table
    from warpskill.robot.plan import PlanError
    from warpskill.robot.replaying import replay
    from warpskill.robot.retargeting import retarget
    from warpskill.robot.video import prefer_headless_gl, record

    prefer_headless_gl()

    actions = list(actions or ACTIONS)
    rows: dict[str, list] = {"planned": [], **{f"replay {engine}": [] for engine in engines}}
    planning: list[float] = []
    replaying: dict[str, list[float]] = {engine: [] for engine in engines}
    failures: list[str] = []
    for action in actions:
        for seed in range(seeds):
            folder = out / f"{action}_{seed}" if out is not None else None
            if folder is not None:
                folder.mkdir(parents=True, exist_ok=True)
            recon = synthetic_reconstruction(action, seed, source, folder=folder, device=device)
            try:
                plan = retarget(recon)
            except PlanError as error:
                rows["planned"].append((action, False))
                for engine in engines:
                    rows[f"replay {engine}"].append((action, False))
                failures.append(f"{action} seed {seed}: plan: {error}")
                print(f"{action:<22} seed {seed}: no plan ({str(error)[:90]})", flush=True)
                continue
            planning.append(plan.planning_time)
            rows["planned"].append((action, True))
            if folder is not None:
                plan.save(folder / "plan.npz")
            verdicts = []
            recorded = None
            for engine in engines:
                result = replay(plan, recon, engine=engine, device=None if engine == "mujoco" else device)
                if video and folder is not None and recorded is None:
                    recorded = record(plan, plan.scene(recon), result, folder)
                replaying[engine].append(result.replay_time)
                rows[f"replay {engine}"].append((action, result.success))
                if not result.success:
                    failed = [name for name, ok in result.evaluation.checks.items() if not ok]
                    failures.append(f"{action} seed {seed}: {engine} replay fails {', '.join(failed)}")
                verdicts.append(f"{engine} {'ok  ' if result.success else 'fail'} {result.replay_time:5.1f} s")
            where = "" if plan.offset is None else (f", at ({plan.offset[0]:.2f}, {plan.offset[1]:.2f}) m "
                                                    f"{math.degrees(plan.yaw):.0f} deg")
            resized = ", substituted object" if plan.note else ""
            print(f"{action:<22} seed {seed}: planned {plan.planning_time:4.1f} s ({plan.grasp_name}{where}{resized}); "
                  + "; ".join(verdicts), flush=True)

    print()
    print(f"reconstructions: {source}")
    print(success_table(rows))
    print()
    if planning:
        print(f"planning time per plan: median {statistics.median(planning):.2f} s, max {max(planning):.2f} s")
    for engine, seconds in replaying.items():
        if seconds:
            print(f"{engine} replay time per plan: median {statistics.median(seconds):.2f} s, max {max(seconds):.2f} s")
    if failures:
        print("failures:")
        for line in failures:
            print(f"  {line}")
    return {"rows": rows, "planning": planning, "replay": replaying, "failures": failures}
