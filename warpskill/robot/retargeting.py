"""Retargeting a reconstruction to the Panda with placo: the robot performs the demonstrated skill.

:func:`retarget`:

1. the robot's reconstruction (:func:`robot_reconstruction`): the robot's own object sizes
   (:mod:`warpskill.robot.sizes`), or a substitute for a grasped cuboid wider than the
   gripper on every face that is no open vessel held by its rim (``keep_size`` refuses
   instead); an object held from the first
   frame (carried into view: its start is unknown) starts resting below the first frame
   from which the robot can do the task, the grasp onset;
2. grasp poses (:mod:`warpskill.robot.grasps`) ranked against the demonstrated approach;
3. placement (:mod:`warpskill.robot.placement`): with ``placement="auto"`` (the default)
   a deterministic search of the base pose scored on the task's key poses, a base from which
   the whole held path keeps :data:`~warpskill.robot.placement.REACH_MARGIN` inside the
   arm's reach first; a given
   :class:`~warpskill.robot.model.Placement` fixes it;
4. at each of the best placements, the feasible grasp poses (static IK of the grasp, the
   pre-grasp and, for a carried object, the set-down pose) are planned in order of cost
   (closest to the demonstrated approach, nearest the home configuration): the targets
   of :mod:`warpskill.robot.targets` (from home onto the demonstrated path a margin before
   the contact, through the contact and the release, then away), one differential-IK step
   per sample (:class:`~warpskill.robot.planner.Planner`); a plan that cannot track the
   demonstration is retried 1.7 and 3 times slower, then joining at the pre-grasp.

A put onto lets go with the object's bottom just above the static box's top (its centre
inside the top: :func:`~warpskill.robot.targets.onto_release`, the carried object's own
size), the held path blending into that release; the replay checks that it stays there.

A plan that cannot be made raises :class:`PlanError` naming the frame and why, in one line.

With a ``layout`` (:class:`~warpskill.contract.skill.Layout`), the reconstruction's skill
(:func:`~warpskill.robot.skill_layout.skill_from`) is carried there first
(:func:`~warpskill.robot.skill_layout.apply_skill`) and the plan made for that reconstruction;
the plan carries the layout, so that the replays simulate it. A layout the Panda cannot
serve from any base placement (:func:`~warpskill.robot.placement.check_reach`), or one the
skill cannot be carried to, raises :class:`~warpskill.contract.skill.LayoutError`. In a
layout, an object held from the first frame is taken where the layout starts it.
"""

from __future__ import annotations

import heapq
import time

import numpy as np

from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.skill import Layout, Skill
from warpskill.geometry import NEVER_HELD, held_span, is_held
from warpskill.nouns.typical import is_open_topped
from warpskill.robot.grasps import FIT_MARGIN, GraspPose, candidate_poses, rank_poses
from warpskill.robot.model import HOME_Q, MAX_OPENING, Placement, Scene, make_scene
from warpskill.robot.placement import WRIST, check_reach, rank_placements, reach_excess
from warpskill.robot.plan import PlanError, RobotPlan
from warpskill.robot.planner import DT, Planner
from warpskill.robot.sizes import clear_path, fit_sizes, rest_until
from warpskill.robot.skill_layout import SWING_SPEED, apply_skill, demonstrated_layout, skill_from
from warpskill.robot.targets import (
    PREGRASP,
    hold_pose,
    key_targets,
    lift_clear,
    onto_release,
    plan_targets,
    pose_matrix,
    support_height,
    translate,
)

__all__ = ["AUTO", "retarget", "robot_reconstruction"]

AUTO = "auto"
"""``placement=AUTO``: search where the robot stands (:func:`warpskill.robot.placement.rank_placements`)."""

HOOK_PENALTY = 1000.0  # a pull hooks the cuboid only when no grasp is feasible
SHALLOW_PENALTY = 100.0  # a shallow top grasp is taken only when the deeper ones are infeasible
OFF_CENTRE_PENALTY = 45.0  # [deg equivalent] edge, side and rim grasps hold a carried cuboid off its centre: it swings
RIM_PENALTY = 20.0  # [deg equivalent] a rim grasp comes after the face grasps (further off the centre)
RELEASE_SHIFTS = (0.01, 0.02, 0.035, 0.05, 0.075, 0.1)  # [m] tried moves of the set-down place away from a static box, along the fingers
SHIFT_PENALTY = 5000.0  # per metre of release shift
NEAR_SHIFT = 0.05  # [m] a release shift further than this comes after every other grasp but a hook
FAR_SHIFT_PENALTY = 1000.0
TALL = 0.12  # [m] an object taller than this pivots about an edge grasp (held at its top edge) ...
TALL_EDGE_PENALTY = 90.0  # [deg equivalent] ... which then comes after the side grasps
MIN_PUSH_TRAVEL = 0.01  # [m] a push or pull moving the object less than this keeps the demonstrated approach
SET_DOWN_HEIGHT = 0.1  # [m] the release pose's reachability is checked coming down from this high above it
SLOWDOWNS = (1.0, 1.7, 3.0)  # the demonstration is replayed this many times slower when the robot lags
PLANNED_POSES = 4  # feasible grasp poses planned in full per placement
SCORED_POSES = 2  # grasp poses whose key poses score a placement
FULL_PLANS = 3  # placements planned in full (auto), best first
CARRY_SPEED = SWING_SPEED  # [m/s] fastest demonstrated object the robot takes over (the Panda's Cartesian speed limit)


def retarget(recon: Reconstruction | Skill, *, layout: Layout | None = None, placement: Placement | str | None = AUTO,
             object_size=None, static_sizes=None, keep_size: bool = False) -> RobotPlan:
    """Plan the Panda motion that performs the reconstructed manipulation.

    Args:
        recon: the reconstruction (hand tip, grasp, object and static cuboids), or its skill.
        layout: where the skill is to run (the object's start, the static boxes); None: the
            demonstrated layout (a reconstruction is then planned exactly as given).
        placement: where the robot stands relative to the scene: ``"auto"`` (default, or
            None) searches it; a :class:`Placement` fixes it.
        object_size: (3,) [m] the robot's object (default: the reconstructed cuboid); the
            demonstrated centre path is kept, its heights follow the size.
        static_sizes: (K, 3) [m] the robot's static cuboids, one per static object.
        keep_size: refuse (PlanError) a grasped cuboid too wide for the gripper instead of
            substituting one that fits.

    A demonstration whose object cannot be grasped where it is first touched (out of the arm's
    reach from every placement: far off, or still being swung into view) is planned once more
    with the object taken over where the robot can do the task from, as one carried into view
    is (:func:`robot_reconstruction`).

    Returns:
        The plan, with ``planning_time`` [s], the placement and the sizes used set.

    Raises:
        PlanError: no feasible grasp or an unreachable target; the message names the
            reconstruction frame and why.
        LayoutError: a layout the skill cannot be carried to, or whose held path does not
            keep :data:`~warpskill.robot.placement.REACH_MARGIN` inside the Panda's reach from
            any base placement (one line naming why).
        ValueError: sizes of the wrong shape or count.
    """
    started = time.perf_counter()
    auto = placement is None or (isinstance(placement, str) and placement == AUTO)
    if isinstance(placement, str) and not auto:
        raise ValueError(f"placement must be 'auto' or a Placement, got {placement!r}")
    if isinstance(recon, Skill) or layout is not None:
        skill = recon if isinstance(recon, Skill) else skill_from(recon)
        layout = demonstrated_layout(skill) if layout is None else layout
        recon = apply_skill(skill, layout)
        check_reach(recon, None if auto else placement)
    sizes = {"object_size": object_size, "static_sizes": static_sizes, "keep_size": keep_size}
    where = Placement() if auto else placement
    robot_recon, note = robot_reconstruction(recon, placement=where, onset=0 if layout is not None else None, **sizes)
    try:
        plan = _plan_anywhere(robot_recon, placement, auto)
    except PlanError as error:
        if layout is not None or is_held(recon.grasped[0]) or not getattr(error, "at_onset", False):
            raise
        plan, note = _taken_over(recon, where, placement, auto, sizes, error)
    plan.note = note
    plan.layout = layout
    plan.planning_time = time.perf_counter() - started
    return plan


def _taken_over(recon: Reconstruction, where: Placement, placement, auto: bool, sizes: dict,
                error: PlanError) -> tuple[RobotPlan, str]:
    """The plan with the object taken over as one carried into view (``swung_in``: first touched out
    of the arm's reach, far off or still being swung in), and the sizes' note; ``error``, the
    demonstration's own, where that gives no plan either."""
    robot_recon, note = robot_reconstruction(recon, placement=where, swung_in=True, **sizes)
    try:
        return _plan_anywhere(robot_recon, placement, auto), note
    except PlanError:
        raise error from None


def _plan_anywhere(recon: Reconstruction, placement: Placement | str | None, auto: bool) -> RobotPlan:
    """The plan of the robot's reconstruction from the best base placement that gives one (``auto``: the
    ranked search, else ``placement``); raises the first placement's PlanError where none does."""
    task = _task(recon)
    if auto:
        scene0 = make_scene(recon)
        scored = [pose for _, _, pose in task["ranked"][:SCORED_POSES]]
        keys = [key_targets(recon, scene0, pose, task["k_on"], task["k_off"]) for pose in scored]
        paths = [_path_wrists(recon, scene0, pose, task["k_on"], task["k_off"]) for pose in scored]
        placements = rank_placements(recon, keys, count=FULL_PLANS, paths=paths)
    else:
        placements = [placement]
    errors = []
    for where in placements:
        try:
            plan = _plan_at(recon, make_scene(recon, where), task)
        except PlanError as error:
            errors.append(error)
            continue
        plan.offset = np.asarray(where.offset, float)
        plan.yaw = float(where.yaw)
        plan.placement = AUTO if auto else "given"
        plan.object_size = recon.object_size.copy()
        plan.object_pos = recon.object_pos.copy()
        plan.object_rot = recon.object_rot.copy()
        plan.static_pos = recon.static_pos.copy()
        plan.static_size = recon.static_size.copy()
        plan.static_rot = recon.static_rot.copy()
        plan.object_noun = str(recon.object_noun)
        return plan
    raise errors[0]


def robot_reconstruction(recon: Reconstruction, *, placement: Placement = Placement(), object_size=None,
                         static_sizes=None, keep_size: bool = False, onset: int | None = None,
                         swung_in: bool = False) -> tuple[Reconstruction, str]:
    """The reconstruction as the robot performs it, and :func:`~warpskill.robot.sizes.fit_sizes`' note.

    The cuboids get the robot's sizes (:func:`~warpskill.robot.sizes.fit_sizes`). An object
    held (pushed, pulled: touched) from the first frame was carried into view, or moved
    before it: its start is unknown. The robot stands at ``placement`` for the part of the
    task it does in any case (the object taken at the last held frame) and takes the object
    at the first held frame k from which it can do the task: the object, resting below its
    frame-k centre, is within reach (static IK reaches a ranked grasp pose and its
    pre-grasp, the pose's other key poses lie within the arm's reach) and the demonstration
    moves it no faster than :data:`CARRY_SPEED` to the next frame (a faster object is still
    being swung into view). The object rests there until k
    (:func:`~warpskill.robot.sizes.rest_until`); below the first held frame where no frame
    qualifies. Every object path is then made one the robot can follow
    (:func:`~warpskill.robot.sizes.clear_path`: never inside its support, no steps down
    while held). This is the one place that decides the object's start: the plan carries the
    result (:meth:`RobotPlan.scene`), which the replays and the video simulate.

    A layout's reconstruction (:func:`~warpskill.robot.skill_layout.apply_skill`) starts a
    carried-in object resting on the table at its take-over pose, where the robot is to take
    it: ``onset=0`` takes it there, on the layout's path as it is (sizes fitted, path cleared),
    whichever placement the search then finds.

    Args:
        recon: the reconstruction.
        placement: where the robot stands (for an object held from the first frame).
        object_size, static_sizes, keep_size: as for :func:`retarget`.
        onset: the held frame at which the robot takes an object held from the first frame
            (None: the first one it can, as above).
        swung_in: take the object over as one held from the first frame, though it is not
            (:func:`retarget` does, where the demonstration as it is gives no plan).

    Raises:
        ValueError: sizes of the wrong shape or count.
    """
    fitted, note = fit_sizes(recon, object_size=object_size, static_sizes=static_sizes, keep_size=keep_size)
    if not (is_held(fitted.grasped[0]) or swung_in):
        return clear_path(fitted), note
    held = np.flatnonzero(is_held(fitted.grasped))
    taken_at = lambda k: clear_path(rest_until(fitted, int(k)))  # noqa: E731
    if onset == 0:  # a layout's: the object rests at its start already; the path is the layout's
        return clear_path(fitted), note
    if onset is not None:
        return taken_at(held[np.searchsorted(held, onset)] if onset <= held[-1] else held[-1]), note
    base = make_scene(taken_at(held[-1]), placement).base
    speed = np.append(np.linalg.norm(np.diff(recon.object_pos, axis=0), axis=1) * float(recon.fps), 0.0)  # (F,)
    for k in held[speed[held] <= CARRY_SPEED]:
        robot_recon = taken_at(k)
        if _reachable(robot_recon, base):
            return robot_recon, note
    return taken_at(held[0]), note


def _reachable(recon: Reconstruction, base: np.ndarray) -> bool:
    """Whether the robot at ``base`` (4, 4) can take the object at the grasp onset and do the rest of the task.

    Some ranked grasp pose has all its key poses (:func:`~warpskill.robot.targets.key_targets`)
    within the arm's reach (:func:`~warpskill.robot.placement.reach_excess`), and static IK
    reaches it and its pre-grasp. False where no pose fits (the plan then says why).
    """
    try:
        task = _task(recon)
    except PlanError:
        return False
    k_on = task["k_on"]
    scene = make_scene(recon, base=base)
    near = [pose for _, _, pose in task["ranked"]
            if reach_excess(base, [key_targets(recon, scene, pose, k_on, task["k_off"])]) == 0.0]
    if not near:
        return False
    planner = Planner(scene)
    T_on = pose_matrix(recon.object_pos[k_on], recon.object_rot[k_on])
    return any(_grasp_ik(planner, T_on, pose)[0] is not None for pose in near)


def _path_wrists(recon: Reconstruction, scene: Scene, pose: GraspPose, k_on: int, k_off: int | None) -> np.ndarray:
    """(M, 3) the wrist points of ``pose``'s whole held path: every reconstruction frame from the
    grasp onset to the release (or the end), and the pre-grasp and the retreat."""
    end = k_off if k_off is not None else recon.num_frames - 1
    poses = [hold_pose(recon, scene, pose, k_on, k_off, float(recon.t[k]), np.zeros(3)) for k in range(k_on, end + 1)]
    poses += key_targets(recon, scene, pose, k_on, k_off)
    return np.array([T[:3, 3] - WRIST * T[:3, 2] for T in poses])


def _grasp_ik(planner: Planner, T_on: np.ndarray, pose: GraspPose) -> tuple[np.ndarray | None, str]:
    """``(q, "")``: static IK reaches ``pose`` on the object at ``T_on`` and its pre-grasp; else ``(None, why)``."""
    q, why = planner.static_ik(T_on @ pose.pose)
    if q is None:
        return None, why
    q_pre, why = planner.static_ik(T_on @ pose.pose @ translate(0, 0, -PREGRASP), q)
    return (q, "") if q_pre is not None else (None, why)


def _task(recon: Reconstruction) -> dict:
    """The contact onset and end, and the grasp poses ranked by (angle + penalties) against the demonstration."""
    action = str(recon.action)
    span = held_span(recon.grasped)
    if span is None:
        raise PlanError(f"frame -: {NEVER_HELD}")
    k_on, k_off = span
    if action == "pick_up":
        k_off = None  # a picked-up object ends in the hand: a release in the last frames is not followed
    pushing = action.startswith("push_")
    same_side = action.startswith(("push_", "pull_"))
    R_on = recon.object_rot[k_on]
    axis = recon.hand_rot[k_on][:, 2]
    push_height = float(R_on[:, 2] @ (recon.hand_pos[k_on] - recon.object_pos[k_on]))
    poses = candidate_poses(R_on, recon.object_size, push_height=push_height, pushing=pushing,
                            hooking=action.startswith("pull_"), open_top=is_open_topped(str(recon.object_noun)))
    if not poses:
        size = " x ".join(f"{s:.3f}" for s in recon.object_size)
        raise PlanError(
            f"frame {k_on} (t = {recon.t[k_on]:.2f} s, grasp onset): no feasible grasp: the {size} m cuboid is "
            f"wider than the gripper's {MAX_OPENING - FIT_MARGIN:.3f} m usable opening across every face, "
            "with no rim to hold"
        )
    ranked = rank_poses(poses, R_on, axis, push_direction=_push_direction(recon, k_on, k_off, axis) if same_side
                        else None)
    if not ranked:
        raise PlanError(f"frame {k_on} (t = {recon.t[k_on]:.2f} s, grasp onset): no grasp pose faces "
                        "the demonstrated push or pull")
    height = float(np.abs(R_on[2]) @ recon.object_size)  # the cuboid's vertical extent at the onset
    ranked = sorted(((angle + _penalty(pose, height), angle, pose) for angle, pose in ranked),
                    key=lambda item: item[0])
    return {"k_on": k_on, "k_off": k_off, "pushing": pushing, "ranked": ranked, "height": height}


def _penalty(pose: GraspPose, height: float) -> float:
    """The structural cost of a pose: hooks, shallow grasps, grasps off the centre (rims the furthest, and
    edge grasps of a tall object) come last."""
    cost = HOOK_PENALTY if pose.standoff > 0 else 0.0
    cost += RIM_PENALTY if pose.name.startswith("rim_") else 0.0
    cost += TALL_EDGE_PENALTY if pose.name.startswith("edge_") and height > TALL else 0.0
    cost += SHALLOW_PENALTY if pose.name.endswith("_shallow") else 0.0
    cost += OFF_CENTRE_PENALTY if pose.kind == "grasp" and not pose.name.startswith("top_") else 0.0
    return cost


def _plan_at(recon: Reconstruction, scene: Scene, task: dict) -> RobotPlan:
    """The plan at one placement: the feasible poses in order of cost, each tried in full."""
    k_on, k_off = task["k_on"], task["k_off"]
    planner = Planner(scene)
    T_on = pose_matrix(recon.object_pos[k_on], recon.object_rot[k_on])
    T_off = None
    onto = None  # a put onto's move of the release onto the static box's top
    if k_off is not None and not task["pushing"]:
        T_off = pose_matrix(recon.object_pos[k_off], recon.object_rot[k_on])
        if str(recon.action) == "put_onto" and len(scene.static_pos):
            placed = onto_release(scene, T_off, recon.object_size)
            onto, T_off = placed[:3, 3] - T_off[:3, 3], placed
        else:
            T_off = lift_clear(T_off, recon.object_size, support_height(scene, T_off, recon.object_size))
    task = {**task, "onto": onto}
    rejected = []  # (pose name, why)
    failures = []
    planner.set_q(HOME_Q, MAX_OPENING)
    home_tcp = planner.tcp()
    for _, pose, shift in _feasible(planner, scene, task, T_on, T_off, rejected):
        # The demonstrated approach first; where the robot cannot follow it, joining at the pre-grasp.
        # Slowing down helps only a lagging TCP; another approach only a failure before the grasp.
        reported = None  # the demonstrated approach's first failure
        for follow_hand in (True, False):
            for slow in SLOWDOWNS:
                try:
                    return _plan(recon, scene, planner, pose, k_on, k_off, slow, shift, home_tcp, follow_hand)
                except PlanError as error:
                    reported = reported or error
                    last = error
                    if getattr(error, "kind", "reach") != "reach":
                        break
            if getattr(last, "after_grasp", False):
                break
        failures.append(f"{pose.name}: {reported}")
        if len(failures) == PLANNED_POSES:
            break
    if not failures:
        reasons = "; ".join(f"{name}: {why}" for name, why in rejected[:6])
        error = PlanError(f"frame {k_on} (t = {recon.t[k_on]:.2f} s, grasp onset): no feasible grasp pose "
                          f"({reasons})")
        error.at_onset = True  # the object cannot be taken where it is first touched
        raise error
    raise PlanError("; ".join(failures))


def _feasible(planner: Planner, scene: Scene, task: dict, T_on: np.ndarray, T_off: np.ndarray | None,
              rejected: list):
    """The feasible grasp poses, cheapest first: ``(cost, pose, release shift)``; infeasible ones go to ``rejected``.

    A pose is feasible when static IK reaches it, its pre-grasp and (a carried object) its
    set-down pose. The cost (angle to the demonstrated approach + the pose's penalty +
    distance of its configuration from home + release shift) is never below the ranking's
    angle + penalty, so poses are checked lazily, only while one could still come first.
    """
    k_off = task["k_off"]
    ranked = task["ranked"]
    ready: list = []  # heap of (cost, order, pose, shift)
    i = 0
    while True:
        while i < len(ranked) and (not ready or ready[0][0] > ranked[i][0]):
            _, angle, pose = ranked[i]
            i += 1
            q, why = _grasp_ik(planner, T_on, pose)
            if q is None:
                rejected.append((pose.name, why))
                continue
            shift = np.zeros(3)
            if T_off is not None and pose.kind == "grasp":
                onto = task["onto"] is not None
                shift, why_off = _release_shift(planner, scene, T_off, pose, shifts=() if onto else RELEASE_SHIFTS)
                if shift is None:
                    what = "the release on the static box's top" if onto else "the release"
                    rejected.append((pose.name, f"at {what} (frame {k_off}): {why_off}"))
                    continue
            cost = angle + _penalty(pose, task["height"]) + 10.0 * float(np.abs(q - HOME_Q).sum())
            cost += SHIFT_PENALTY * float(np.linalg.norm(shift))
            cost += FAR_SHIFT_PENALTY if np.linalg.norm(shift) > NEAR_SHIFT + 1e-9 else 0.0
            heapq.heappush(ready, (cost, i, pose, shift if task["onto"] is None else shift + task["onto"]))
        if not ready:
            return
        cost, _, pose, shift = heapq.heappop(ready)
        yield cost, pose, shift


def _push_direction(recon: Reconstruction, k_on: int, k_off: int | None, hand_axis: np.ndarray) -> np.ndarray:
    """(3,) the way the fingers must face to move the object as demonstrated (push and pull).

    A push presses the object along its displacement, a pull (hooking the far face) against
    it, from the hand's side. Without a clear displacement (< :data:`MIN_PUSH_TRAVEL`), the
    demonstrated approach ``-hand_axis`` decides.
    """
    displacement = recon.object_pos[k_off if k_off is not None else -1] - recon.object_pos[k_on]
    displacement[2] = 0.0
    if np.linalg.norm(displacement) < MIN_PUSH_TRAVEL:
        return -np.asarray(hand_axis, float)
    return displacement if str(recon.action).startswith("push_") else -displacement


def _release_shift(planner: Planner, scene: Scene, T_off: np.ndarray, pose: GraspPose,
                   shifts: tuple[float, ...] = RELEASE_SHIFTS):
    """The smallest horizontal move of the set-down pose ``T_off`` that the gripper can reach.

    A finger needs room beside the object: where the demonstration sets the object down
    closer to a static box than a finger's thickness, the set-down place is moved away from
    the nearest static box along the finger axis by one of ``shifts`` (default
    :data:`RELEASE_SHIFTS`; none for a put onto, whose release stays on the box's top).

    Returns:
        ``(shift (3,) [m], "")`` or ``(None, why)``.
    """
    def reachable(T_obj: np.ndarray) -> str:
        # Come down from above, as the carry does, so the IK does not catch on the box's edge.
        q_above, why = planner.static_ik(translate(0, 0, SET_DOWN_HEIGHT) @ T_obj @ pose.pose)
        return why or planner.static_ik(T_obj @ pose.pose, q_above)[1]

    why = reachable(T_off)
    if not why:
        return np.zeros(3), ""
    if len(scene.static_pos) == 0 or not shifts:
        return None, why
    fingers = (T_off @ pose.pose)[:3, 1].copy()
    fingers[2] = 0.0
    if np.linalg.norm(fingers) < 0.5:
        return None, why
    fingers /= np.linalg.norm(fingers)
    nearest = scene.static_pos[np.argmin(np.linalg.norm(scene.static_pos - T_off[:3, 3], axis=1))]
    away = fingers if fingers @ (T_off[:3, 3] - nearest) >= 0 else -fingers
    for distance in shifts:
        shifted = translate(*(distance * away)) @ T_off
        if not reachable(shifted):
            return distance * away, ""
    return None, f"{why}; also when set down up to {100 * shifts[-1]:.0f} cm further from the static box"


def _plan(recon: Reconstruction, scene: Scene, planner: Planner, pose: GraspPose, k_on: int, k_off: int | None,
          slow: float, release_shift: np.ndarray, home_tcp: np.ndarray, follow_hand: bool) -> RobotPlan:
    """Run the differential IK along the targets of ``pose``; raise PlanError on a tracking failure."""
    plan = plan_targets(recon, scene, pose, k_on, k_off, slow, release_shift, home_tcp, follow_hand)
    fps = float(recon.fps)
    taus = plan.taus
    try:
        qs, tcps = planner.track(plan.targets, plan.grips, lead_in=plan.lead_in,
                                 frame_of=lambda i: (int(round(taus[i] * fps)), taus[i]))
    except PlanError as error:
        error.after_grasp = getattr(error, "sample", 0) * DT >= plan.grasp_time
        raise
    return RobotPlan(
        t=np.asarray(plan.times), q=qs, gripper=np.asarray(plan.grips), tcp=tcps, grasp_time=plan.grasp_time,
        release_time=plan.release_time, start_time=plan.start_time, recon_time=np.asarray(taus), base=scene.base,
        grasp_pose=pose.pose, grasp_name=pose.name, grasp_kind=pose.kind, action=str(recon.action),
    )
