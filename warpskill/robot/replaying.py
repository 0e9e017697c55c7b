"""Replaying a robot plan in a physics engine and judging it with the paper's success criteria.

:func:`replay` simulates the Panda, the table and the cuboids under position control of the
plan, samples the gripper and the object at the reconstruction's frame rate from the
plan's ``start_time`` (the end of the lead-in) to its end, and packs them as a
:class:`~warpskill.contract.reconstruction.Reconstruction`: the ``hand_*`` fields hold the gripper's
TCP (hand frame of ``docs/formats.md``: origin at the TCP, local +z from the fingers towards
the arm), ``grasp`` the gripper command (+0.02 closing, -0.02 open), ``grasped`` whether
both fingers touch the object, the ``object_*`` fields the simulated object.

A put onto is judged on more than its final frame: the replay checks the release itself
(:func:`release_checks`: the gripper let go and the object rests, still, on the static box's
top inside its footprint), the check :data:`RELEASE_CHECK` among the replay's checks. (A
``replay.npz`` read back is judged by the paper's criteria alone.)
"""

from __future__ import annotations

import time

import numpy as np

from warpskill.contract.evaluation import Evaluation, evaluate
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.replay import Replay
from warpskill.robot import replay_mujoco
from warpskill.robot.plan import RobotPlan

ENGINES: tuple[str, ...] = ("mujoco", "newton")
RELEASE_CHECK = "released_on_top"
"""The name of the put onto's release check (:func:`release_checks`) among a replay's checks."""
SETTLED = 0.01
"""[m] a released object counts as resting when its centre moves less than this over the
replay's last :data:`SETTLE_WINDOW` (it still slides or rolls otherwise)."""
SETTLE_WINDOW = 0.4  # [s]
ON_TOP = 0.015
"""[m] a released object rests on the static box's top when its lowest corner is within this of
the top (the engines' contacts let it sink a few millimetres)."""
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
    evaluation = evaluate(replayed, action)
    if action == "put_onto" and recon.num_static:
        checks = {**evaluation.checks, **release_checks(replayed, times - plan.start_time, plan.release_time
                                                        - plan.start_time)}
        evaluation = Evaluation(success=all(checks.values()), checks=checks, action=evaluation.action)
    return Replay(replayed, evaluation, engine, elapsed, sim["q"])


def release_checks(replayed: Reconstruction, times: np.ndarray, release_time: float) -> dict[str, bool]:
    """The put onto's release, checked on the replayed object: ``{RELEASE_CHECK: ok}``.

    It holds where the gripper let go (``release_time`` [s] on the replay's clock ``times``;
    no finger touches the object in the last frame) and the object then rests on the first static
    box's top: its centre inside the top's footprint (in the box's frame), its lowest corner
    within :data:`ON_TOP` of the top, and it moved less than :data:`SETTLED` over the last
    :data:`SETTLE_WINDOW`. A release that was planned but ended off the box, tilted against
    it, or still sliding is a failed check (the replay's failure, named so in its checks).
    """
    pos = replayed.object_pos
    local = replayed.static_rot[0].T @ (pos[-1] - replayed.static_pos[0])
    inside = bool(np.all(np.abs(local[:2]) < replayed.static_size[0, :2] / 2))
    top = float(replayed.static_corners()[0, :, 2].max())
    on_top = abs(float(replayed.object_corners()[-1, :, 2].min()) - top) < ON_TOP
    window = times >= times[-1] - SETTLE_WINDOW
    still = float(np.linalg.norm(pos[window] - pos[-1], axis=1).max()) < SETTLED
    released = bool(np.isfinite(release_time) and times[-1] > release_time and replayed.grasped[-1] < 0.5)
    return {RELEASE_CHECK: bool(released and inside and on_top and still)}
