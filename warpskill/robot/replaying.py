"""Replaying a robot plan in a physics engine and judging it with the paper's success criteria.

:func:`replay` simulates the Panda, the table and the cuboids under position control of the
plan, samples the gripper and the object at the reconstruction's frame rate from the
plan's ``start_time`` (the end of the lead-in) to its end, and packs them as a
:class:`~warpskill.contract.reconstruction.Reconstruction`: the ``hand_*`` fields hold the gripper's
TCP (hand frame of ``docs/formats.md``: origin at the TCP, local +z from the fingers towards
the arm), ``grasp`` the gripper command (+0.02 closing, -0.02 open), ``grasped`` whether
both fingers touch the object, the ``object_*`` fields the simulated object.
"""

from __future__ import annotations

import time

import numpy as np

from warpskill.contract.evaluation import evaluate
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.replay import Replay
from warpskill.robot import replay_mujoco
from warpskill.robot.plan import RobotPlan

ENGINES: tuple[str, ...] = ("mujoco", "newton")
GRASP_LEVEL = 0.02  # [m] |grasp| written for the gripper command
_TCP_TO_HAND = np.diag([1.0, -1.0, -1.0])  # TCP frame (z towards the object) -> hand frame (z towards the arm)


def replay(plan: RobotPlan, recon: Reconstruction, engine: str = "mujoco", *, device: str | None = None,
           edit_model=None) -> Replay:
    """Simulate ``plan`` in the scene of ``recon`` and judge the replayed object motion.

    Args:
        plan: from :func:`warpskill.robot.retarget` (or :meth:`RobotPlan.load`).
        recon: the reconstruction the plan was made for (statics, action); the cuboids'
            sizes and poses, the object's start included, are the plan's
            (:meth:`RobotPlan.scene`), as ``replay.npz`` records.
        engine: ``"mujoco"`` (default) or ``"newton"``.
        device: Warp device for Newton (``"cpu"``, ``"cuda"``; default: Warp's default).
        edit_model: MuJoCo only: called with the built ``mujoco.MjModel`` to change it in
            place before the run (a perturbed mass, friction or object start).

    Raises:
        ValueError: an unknown engine, or an action the reconstruction cannot be judged on.
    """
    if engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r}; valid engines: {', '.join(ENGINES)}")
    if edit_model is not None and engine != "mujoco":
        raise ValueError(f"edit_model changes a MuJoCo model; the {engine} replay takes none")
    recon = plan.scene(recon)  # the cuboids the plan was made for (sizes, poses, start): simulated and recorded
    fps = float(recon.fps)
    times = np.arange(plan.start_time, plan.t[-1] + 1e-9, 1.0 / fps)
    started = time.perf_counter()
    if engine == "mujoco":
        sim = replay_mujoco.simulate(plan, recon, times, edit_model=edit_model)
    else:
        from warpskill.robot import replay_newton  # optional extra: robot (Newton, Warp)

        sim = replay_newton.simulate(plan, recon, times, device=device)
    elapsed = time.perf_counter() - started
    closing = np.interp(times, plan.t, plan.gripper) < 0.5 * max(float(plan.gripper.max()), 1e-9)
    if plan.grasp_kind == "grasp":
        after = times >= plan.grasp_time
        before = ~np.isfinite(plan.release_time) | (times < plan.release_time)
        closing = after & before
    n = len(times)
    replayed = Reconstruction(
        fps=recon.fps,
        t=np.arange(n) / fps,
        hand_pos=sim["tcp"][:, :3, 3],
        hand_rot=sim["tcp"][:, :3, :3] @ _TCP_TO_HAND,
        grasp=np.where(closing, GRASP_LEVEL, -GRASP_LEVEL),
        grasped=sim["held"],
        object_pos=sim["object_pos"],
        object_rot=sim["object_rot"],
        object_size=recon.object_size,
        static_pos=recon.static_pos,
        static_rot=recon.static_rot,
        static_size=recon.static_size,
        camera_K=recon.camera_K,
        camera_elevation=recon.camera_elevation,
        camera_height=recon.camera_height,
        image_size=recon.image_size,
        action=recon.action,
        loss=np.array(0.0),
    )
    action = str(recon.action) or plan.action
    return Replay(replayed, evaluate(replayed, action), engine, elapsed, sim["q"])
