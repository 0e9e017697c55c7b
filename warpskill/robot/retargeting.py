"""Retargeting a reconstruction to the Panda with placo: the gripper's TCP follows the hand.

The plan, sampled every :data:`DT`:

1. lead-in (:data:`LEAD_IN` s): from the home configuration to the first pose;
2. approach: the demonstrated tip path, shifted so that it ends at the pre-grasp pose
   (8 cm back along the approach), then a straight move onto the grasp pose at the onset
   (where the robot cannot follow the demonstrated path, it waits at the pre-grasp instead);
3. grasp: the gripper closes (:data:`CLOSE_TIME` s, the arm waits);
4. hold: the TCP keeps the grasp pose on the moving object: a carried object follows its
   reconstructed path upright, in its orientation at the grasp (the reconstruction's turns
   of the object in the hand are fitting noise for these actions, often faster than a
   wrist can follow); a push follows the object's horizontal displacement at the push height;
5. release: the gripper opens (:data:`OPEN_TIME` s) and the TCP backs off along the approach.

Each sample is one differential-IK step (placo ``KinematicsSolver``): a TCP frame task,
joint position and velocity limits (hard), self-collision and table/static-box avoidance
(hard; the environment is fixed to the base in the planner's URDF), a light posture task.
The grasp pose is the feasible predefined pose (:mod:`warpskill.robot.grasps`) closest to
the demonstrated approach; feasibility is a static IK solve, then the whole plan.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
import tempfile
import time

import numpy as np

from warpskill.contract.reconstruction import Reconstruction
from warpskill.robot.grasps import GraspPose, candidate_poses, rank_poses
from warpskill.robot.model import (
    ARM_JOINTS,
    FINGER_JOINTS,
    FINGER_SPEED,
    HOME_Q,
    MAX_OPENING,
    TCP_FRAME,
    Placement,
    Scene,
    collision_pairs,
    make_scene,
    planner_urdf,
)
from warpskill.robot.plan import _CLOSE_TIME as CLOSE_TIME
from warpskill.robot.plan import _OPEN_TIME as OPEN_TIME
from warpskill.robot.plan import PlanError, RobotPlan

DT = 0.02  # [s] plan sample period
LEAD_IN = 2.5  # [s] from home to the first pose
PREGRASP = 0.08  # [m] pre-grasp stand-off along the approach
APPROACH_TIME = 0.6  # [s] from the pre-grasp to the grasp pose
RETREAT = 0.10  # [m] back-off along the approach after the release
RETREAT_TIME = 0.6  # [s]
SETTLE = 0.5  # [s] still time at the end
VELOCITY_SCALE = 0.9  # plan within this fraction of the URDF joint speed limits
LIMIT_MARGIN = 0.02  # [rad] plan this far inside the joint limits
COLLISION_MARGIN = 0.005  # [m] smallest planned distance between checked bodies
SOFT_COLLISION_WEIGHT = 100.0  # weight of the collision constraint when a start must be softened
TRACK_POSITION = 0.01  # [m] largest TCP position error accepted
TRACK_ANGLE = 8.0  # [deg] largest TCP orientation error accepted
LAG_SAMPLES = 10  # the TCP may lag further behind a fast target for this many samples (0.2 s) ...
LAG_POSITION = 0.025  # [m] ... but never by more than this
LAG_ANGLE = 15.0  # [deg] ... or this
CLEARANCE = 0.003  # [m] a carried object is kept this far above its support
HOOK_PENALTY = 1000.0  # a pull hooks the cuboid only when no grasp is feasible
SHALLOW_PENALTY = 100.0  # a shallow top grasp is taken only when the deeper ones are infeasible
OFF_CENTRE_PENALTY = 45.0  # [deg equivalent] edge and side grasps hold a carried cuboid off its centre: it swings
RELEASE_SHIFTS = (0.01, 0.02, 0.035, 0.05)  # [m] tried moves of the set-down place away from a static box, along the fingers
SHIFT_PENALTY = 5000.0  # per metre of release shift
MIN_PUSH_TRAVEL = 0.01  # [m] a push or pull moving the object less than this keeps the demonstrated approach
SET_DOWN_HEIGHT = 0.1  # [m] the release pose's reachability is checked coming down from this high above it
SLOWDOWNS = (1.0, 1.7, 3.0)  # the demonstration is replayed this many times slower when the robot lags


def retarget(recon: Reconstruction, *, placement: Placement | None = None) -> RobotPlan:
    """Plan the Panda motion that performs the reconstructed manipulation.

    Args:
        recon: the reconstruction (hand tip, grasp, object and static cuboids).
        placement: where the robot stands relative to the scene (default :class:`Placement`).

    Returns:
        The plan, with ``planning_time`` [s] set.

    Raises:
        PlanError: no feasible grasp or an unreachable target; the message names the
            reconstruction frame and why.
    """
    started = time.perf_counter()
    action = str(recon.action)
    scene = make_scene(recon, placement)
    held = np.flatnonzero(recon.grasped > 0.5)
    if len(held) == 0:
        raise PlanError("frame -: the hand never grasps or touches the object (grasped <= 0.5 in every frame)")
    k_on = int(held[0])
    k_off = int(held[-1]) + 1 if held[-1] + 1 < recon.num_frames else None
    pushing = action.startswith("push_")
    same_side = action.startswith(("push_", "pull_"))
    R_on = recon.object_rot[k_on]
    axis = recon.hand_rot[k_on][:, 2]
    push_height = float(R_on[:, 2] @ (recon.hand_pos[k_on] - recon.object_pos[k_on]))
    pulling = action.startswith("pull_")
    poses = candidate_poses(R_on, recon.object_size, push_height=push_height, pushing=pushing, hooking=pulling)
    if not poses:
        size = " x ".join(f"{s:.3f}" for s in recon.object_size)
        raise PlanError(
            f"frame {k_on} (t = {recon.t[k_on]:.2f} s, grasp onset): no feasible grasp: the {size} m cuboid is "
            f"wider than the gripper's {MAX_OPENING - 0.006:.3f} m usable opening across every face"
        )
    ranked = rank_poses(poses, R_on, axis, push_direction=_push_direction(recon, k_on, k_off, axis) if same_side
                        else None)
    if not ranked:
        raise PlanError(f"frame {k_on} (t = {recon.t[k_on]:.2f} s, grasp onset): no grasp pose faces "
                        "the demonstrated push or pull")
    planner = _Planner(scene)
    T_on = _pose(recon.object_pos[k_on], R_on)
    T_off = None
    if k_off is not None and not pushing:
        T_off = _pose(recon.object_pos[k_off], R_on)
        T_off = _lift_clear(T_off, recon.object_size, _support_height(scene, T_off, recon.object_size))
    feasible, rejected = [], []  # (cost, pose, release shift), (pose name, why)
    for angle, pose in ranked:
        q, why = planner.static_ik(T_on @ pose.pose)
        q_pre, why_pre = planner.static_ik(T_on @ pose.pose @ _translate(0, 0, -PREGRASP), q)
        if q is None or q_pre is None:
            rejected.append((pose.name, why or why_pre))
            continue
        shift = np.zeros(3)
        if T_off is not None and pose.kind == "grasp":
            shift, why_off = _release_shift(planner, scene, T_off, pose)
            if shift is None:
                rejected.append((pose.name, f"at the release (frame {k_off}): {why_off}"))
                continue
        cost = angle + 10.0 * float(np.abs(q - HOME_Q).sum()) + (HOOK_PENALTY if pose.standoff > 0 else 0.0)
        cost += SHALLOW_PENALTY if pose.name.endswith("_shallow") else 0.0
        cost += OFF_CENTRE_PENALTY if pose.kind == "grasp" and not pose.name.startswith("top_") else 0.0
        cost += SHIFT_PENALTY * float(np.linalg.norm(shift))
        feasible.append((cost, pose, shift))
    if not feasible:
        reasons = "; ".join(f"{name}: {why}" for name, why in rejected[:6])
        raise PlanError(f"frame {k_on} (t = {recon.t[k_on]:.2f} s, grasp onset): no feasible grasp pose "
                        f"({reasons})")
    feasible.sort(key=lambda item: item[0])
    failures = []
    for _, pose, shift in feasible[:4]:
        # The demonstrated approach first; where the robot cannot follow it, a wait at the pre-grasp.
        reported = None  # the demonstrated approach's last failure
        for follow_hand, slow in [(True, slow) for slow in SLOWDOWNS] + [(False, slow) for slow in SLOWDOWNS]:
            try:
                plan = _plan(recon, scene, planner, pose, k_on, k_off, slow, shift, follow_hand=follow_hand)
            except PlanError as error:
                reported = error if follow_hand else reported
                continue
            plan.planning_time = time.perf_counter() - started
            return plan
        failures.append(f"{pose.name}: {reported}")
    raise PlanError("; ".join(failures))


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


def _release_shift(planner: "_Planner", scene: Scene, T_off: np.ndarray, pose: GraspPose):
    """The smallest horizontal move of the set-down pose ``T_off`` that the gripper can reach.

    A finger needs room beside the object: where the demonstration sets the object down
    closer to a static box than a finger's thickness, the set-down place is moved away from
    the nearest static box along the finger axis by one of :data:`RELEASE_SHIFTS`.

    Returns:
        ``(shift (3,) [m], "")`` or ``(None, why)``.
    """
    def reachable(T_obj: np.ndarray) -> str:
        # Come down from above, as the carry does, so the IK does not catch on the box's edge.
        q_above, why = planner.static_ik(_translate(0, 0, SET_DOWN_HEIGHT) @ T_obj @ pose.pose)
        return why or planner.static_ik(T_obj @ pose.pose, q_above)[1]

    why = reachable(T_off)
    if not why:
        return np.zeros(3), ""
    if len(scene.static_pos) == 0:
        return None, why
    fingers = (T_off @ pose.pose)[:3, 1].copy()
    fingers[2] = 0.0
    if np.linalg.norm(fingers) < 0.5:
        return None, why
    fingers /= np.linalg.norm(fingers)
    nearest = scene.static_pos[np.argmin(np.linalg.norm(scene.static_pos - T_off[:3, 3], axis=1))]
    away = fingers if fingers @ (T_off[:3, 3] - nearest) >= 0 else -fingers
    for distance in RELEASE_SHIFTS:
        shifted = _translate(*(distance * away)) @ T_off
        if not reachable(shifted):
            return distance * away, ""
    return None, f"{why}; also when set down up to {100 * RELEASE_SHIFTS[-1]:.0f} cm further from the static box"


def _pose(pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rot
    T[:3, 3] = pos
    return T


def _translate(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _min_jerk(s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5


def _support_height(scene: Scene, T_obj: np.ndarray, size: np.ndarray) -> float:
    """Height [m] of the surface under the object at ``T_obj``: the table or a static box's top."""
    floor = 0.0
    radius = 0.5 * min(size[0], size[1])
    for k in range(len(scene.static_pos)):
        local = scene.static_rot[k].T @ (T_obj[:3, 3] - scene.static_pos[k])
        if np.all(np.abs(local[:2]) < scene.static_size[k, :2] / 2 + radius):
            floor = max(floor, scene.static_pos[k, 2] + scene.static_size[k, 2] / 2)
    return floor


def _lift_clear(T_obj: np.ndarray, size: np.ndarray, floor: float) -> np.ndarray:
    """``T_obj`` raised so that the cuboid's lowest corner is at least :data:`CLEARANCE` above ``floor``."""
    signs = np.array([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    corners = T_obj[:3, 3] + (signs * size / 2) @ T_obj[:3, :3].T
    lift = floor + CLEARANCE - corners[:, 2].min()
    if lift > 0:
        T_obj = T_obj.copy()
        T_obj[2, 3] += lift
    return T_obj


def _targets(recon: Reconstruction, scene: Scene, pose: GraspPose, k_on: int, k_off: int | None, slow: float,
             release_shift: np.ndarray, follow_hand: bool = True):
    """Plan samples: times, reconstruction times, TCP targets (T, 4, 4), gripper openings, events.

    The demonstration is played ``slow`` times slower than recorded; the carried object
    drifts linearly by ``release_shift`` (3,) [m] from the grasp to the release. Without
    ``follow_hand`` the gripper waits at the pre-grasp pose instead of following the
    demonstrated hand path there.
    """
    step = DT / slow
    t_on = float(recon.t[k_on])
    t_off = float(recon.t[k_off]) if k_off is not None else None
    t_end = float(recon.t[-1])
    T_on = _pose(recon.object_pos[k_on], recon.object_rot[k_on])
    G = T_on @ pose.pose  # the grasp pose in the world at the onset
    approach = G[:3, 2]
    # A hook comes down beside the face (G_down) and moves onto it while the gripper would close.
    outward = approach - (approach @ np.array([0.0, 0.0, 1.0])) * np.array([0.0, 0.0, 1.0])
    G_down = G.copy()
    G_down[:3, 3] += pose.standoff * outward / max(np.linalg.norm(outward), 1e-9)
    pregrasp = G_down @ _translate(0, 0, -PREGRASP)
    app_time = min(APPROACH_TIME, 0.5 * t_on) if t_on > 0 else 0.0
    t_pre = t_on - app_time
    path_shift = pregrasp[:3, 3] - _interp_path(recon.hand_pos, recon.t, t_pre)  # the hand path ends at the pre-grasp
    opening = 0.0 if pose.kind == "push" else min(MAX_OPENING, pose.width + 0.02)
    close_ramp = max(opening / (2 * FINGER_SPEED), DT)
    times, taus, targets, grips = [], [], [], []

    def add(tau: float, T: np.ndarray, grip: float) -> None:
        times.append(len(times) * DT)
        taus.append(tau)
        targets.append(T)
        grips.append(grip)

    def approach_target(tau: float) -> np.ndarray:
        if tau <= t_pre:
            T = G.copy()
            T[:3, 3] = _interp_path(recon.hand_pos, recon.t, tau) + path_shift if follow_hand else pregrasp[:3, 3]
            return T
        s = _min_jerk(np.array((tau - t_pre) / max(app_time, 1e-9)))
        T = G.copy()
        T[:3, 3] = (1 - s) * pregrasp[:3, 3] + s * G_down[:3, 3]
        return T

    def hold_target(tau: float) -> np.ndarray:
        T_obj = _pose(_interp_path(recon.object_pos, recon.t, tau), T_on[:3, :3])
        if t_off is not None:
            T_obj[:3, 3] += release_shift * float(np.clip((tau - t_on) / max(t_off - t_on, 1e-9), 0.0, 1.0))
        if pose.kind == "push":
            T = G.copy()
            T[:2, 3] += T_obj[:2, 3] - T_on[:2, 3]
            return T
        T_obj = _lift_clear(T_obj, recon.object_size, _support_height(scene, T_obj, recon.object_size))
        return T_obj @ pose.pose

    first = approach_target(0.0)
    for _ in range(int(round(LEAD_IN / DT))):
        add(0.0, first, opening)
    start_time = len(times) * DT
    for tau in np.arange(0.0, t_on, step):
        add(float(tau), approach_target(float(tau)), opening)
    grasp_time = len(times) * DT
    n_close = int(round(CLOSE_TIME / DT))
    for i in range(n_close):
        T = G.copy()
        T[:3, 3] = G_down[:3, 3] + _min_jerk(np.array((i + 1) / n_close)) * (G[:3, 3] - G_down[:3, 3])
        add(t_on, T, opening * max(0.0, 1.0 - (i * DT) / close_ramp))
    hold_end = t_off if t_off is not None else t_end
    for tau in np.arange(t_on, hold_end, step):
        add(float(tau), hold_target(float(tau)), 0.0)
    if t_off is None:
        last = hold_target(t_end)
        for _ in range(int(round(SETTLE / DT))):
            add(t_end, last, 0.0)
        return times, taus, targets, grips, start_time, grasp_time, math.nan
    release_time = len(times) * DT
    placed = hold_target(t_off)
    for i in range(int(round(OPEN_TIME / DT))):
        add(t_off, placed, opening * min(1.0, (i * DT) / close_ramp))
    for tau in np.arange(t_off, t_end + SETTLE, step):
        s = _min_jerk(np.array((tau - t_off) / RETREAT_TIME))
        T = placed.copy()
        T[:3, 3] -= s * RETREAT * approach
        add(float(min(tau, t_end)), T, opening)
    return times, taus, targets, grips, start_time, grasp_time, release_time


def _interp_path(path: np.ndarray, t: np.ndarray, tau: float) -> np.ndarray:
    """The point (3,) of ``path`` (T, 3) sampled at times ``t`` at time ``tau`` (linear)."""
    return np.array([np.interp(tau, t, path[:, i]) for i in range(3)])


def _plan(recon, scene, planner: "_Planner", pose: GraspPose, k_on: int, k_off: int | None, slow: float,
          release_shift: np.ndarray, *, follow_hand: bool = True) -> RobotPlan:
    """Run the differential IK along the targets of ``pose``; raise PlanError on a tracking failure."""
    times, taus, targets, grips, start_time, grasp_time, release_time = _targets(
        recon, scene, pose, k_on, k_off, slow, release_shift, follow_hand)
    fps = float(recon.fps)
    qs, tcps = planner.track(targets, grips, lead_in=int(round(LEAD_IN / DT)),
                             frame_of=lambda i: (int(round(taus[i] * fps)), taus[i]))
    return RobotPlan(
        t=np.asarray(times), q=qs, gripper=np.asarray(grips), tcp=tcps, grasp_time=grasp_time,
        release_time=release_time, start_time=start_time, recon_time=np.asarray(taus), base=scene.base,
        grasp_pose=pose.pose, grasp_name=pose.name, grasp_kind=pose.kind, action=str(recon.action),
    )


@contextlib.contextmanager
def _quiet_stdout():
    """Silence C-level stdout and stderr (placo reports self-collisions of the neutral pose when loading)."""
    import ctypes

    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            os.dup2(null.fileno(), 2)
            try:
                yield
            finally:
                ctypes.CDLL(None).fflush(None)
    finally:
        for fd, saved_fd in zip((1, 2), saved):
            os.dup2(saved_fd, fd)
            os.close(saved_fd)


def _rotation_error_deg(A: np.ndarray, B: np.ndarray) -> float:
    c = (np.trace(A.T @ B) - 1.0) / 2.0
    return math.degrees(math.acos(float(np.clip(c, -1.0, 1.0))))


class _Planner:
    """placo robot + kinematics solver for one scene."""

    def __init__(self, scene: Scene):
        import placo

        self.placo = placo
        with _quiet_stdout():
            self.robot = placo.RobotWrapper("", 0, planner_urdf(scene))
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
            json.dump([list(p) for p in collision_pairs(scene)], f)
        try:
            self.robot.load_collision_pairs(f.name)
        finally:
            os.unlink(f.name)
        self.robot.set_T_world_fbase(scene.base)
        for name in ARM_JOINTS:
            lo, hi = self.robot.get_joint_limits(name)
            self.robot.set_joint_limits(name, lo + LIMIT_MARGIN, hi - LIMIT_MARGIN)
        self.solver = placo.KinematicsSolver(self.robot)
        self.solver.mask_fbase(True)
        for name in FINGER_JOINTS:
            self.solver.mask_dof(name)
        self.solver.enable_joint_limits(True)
        self.solver.enable_velocity_limits(True)
        self.task = self.solver.add_frame_task(TCP_FRAME, np.eye(4))
        self.task.configure("tcp", "soft", 1.0, 0.5)
        self.posture = self.solver.add_joints_task()
        self.posture.set_joints({name: float(v) for name, v in zip(ARM_JOINTS, HOME_Q)})
        self.posture.configure("posture", "soft", 1e-5)
        self.collisions = self.solver.add_avoid_self_collisions_constraint()
        self.collisions.self_collisions_margin = COLLISION_MARGIN
        self.collisions.self_collisions_trigger = 0.04
        self.collisions.configure("collisions", "hard")
        self.solver.add_regularization_task(1e-5)
        self.velocity = {}
        for name in ARM_JOINTS:
            self.velocity[name] = float(self.robot.model.velocityLimit[self.robot.get_joint_v_offset(name)])
            self.robot.set_velocity_limit(name, VELOCITY_SCALE * self.velocity[name])

    def set_q(self, q: np.ndarray, opening: float) -> None:
        for name, v in zip(ARM_JOINTS, q):
            self.robot.set_joint(name, float(v))
        for name in FINGER_JOINTS:
            self.robot.set_joint(name, opening / 2)
        self.robot.update_kinematics()

    def q(self) -> np.ndarray:
        return np.array([self.robot.get_joint(name) for name in ARM_JOINTS])

    def tcp(self) -> np.ndarray:
        return np.array(self.robot.get_T_world_frame(TCP_FRAME))

    def step(self, target: np.ndarray, dt: float, *, soften: bool = False) -> None:
        """One IK step towards ``target``; with ``soften``, an infeasible QP is retried with soft collisions.

        Softening lets a start that violates the hard collision margin (the home pose near a
        static box, or a pose on a cuboid's face) move out of it instead of failing.
        """
        self.solver.dt = dt
        self.task.T_world_frame = target
        try:
            self.solver.solve(True)
        except RuntimeError as error:  # an infeasible QP (placo.QPError)
            if not soften:
                raise PlanError(f"the IK problem became infeasible ({error})") from None
            self.collisions.configure("collisions", "soft", SOFT_COLLISION_WEIGHT)
            try:
                self.solver.solve(True)
            except RuntimeError as error:
                raise PlanError(f"the IK problem became infeasible ({error})") from None
            finally:
                self.collisions.configure("collisions", "hard")
        self.robot.update_kinematics()

    def min_distance(self) -> float:
        """Smallest distance [m] between the checked bodies (negative: penetration)."""
        return min((d.min_distance for d in self.robot.distances()), default=math.inf)

    def error(self, target: np.ndarray) -> tuple[float, float]:
        T = self.tcp()
        return float(np.linalg.norm(T[:3, 3] - target[:3, 3])), _rotation_error_deg(T[:3, :3], target[:3, :3])

    def static_ik(self, target: np.ndarray, q0: np.ndarray | None = None, iterations: int = 150):
        """Configuration reaching ``target`` from ``q0`` (home) or (None, why)."""
        self.set_q(HOME_Q if q0 is None else q0, MAX_OPENING)
        self.solver.enable_velocity_limits(False)
        try:
            for _ in range(iterations):
                self.step(target, 0.05, soften=True)
        except PlanError as error:
            return None, str(error)
        finally:
            self.solver.enable_velocity_limits(True)
        pos, ang = self.error(target)
        if pos > TRACK_POSITION / 2 or ang > TRACK_ANGLE / 2:
            return None, f"out of reach ({100 * pos:.1f} cm, {ang:.0f} deg away{self._why()})"
        if self.min_distance() < COLLISION_MARGIN - 1e-3:
            return None, f"in collision{self._why()}"
        return self.q(), ""

    def _why(self) -> str:
        """Which joints sit at a limit and which bodies touch, for error messages."""
        notes = []
        for name in ARM_JOINTS:
            lo, hi = self.robot.get_joint_limits(name)
            v = self.robot.get_joint(name)
            if v - lo < 0.01 or hi - v < 0.01:
                notes.append(f"{name} at its limit")
        model = self.robot.collision_model
        for d in self.robot.distances():
            if d.min_distance < COLLISION_MARGIN + 0.002:
                a = model.geometryObjects[d.objA].name.rsplit("_", 1)[0]
                b = model.geometryObjects[d.objB].name.rsplit("_", 1)[0]
                notes.append(f"{a} against {b}")
        notes = list(dict.fromkeys(notes))
        return ("; " + ", ".join(notes[:4])) if notes else ""

    def track(self, targets, grips, *, lead_in: int, frame_of):
        """Follow ``targets`` one IK step per sample; joint positions (T, 7) and TCP poses (T, 4, 4)."""
        self.set_q(HOME_Q, grips[0])
        lagging = 0  # consecutive samples off the target by more than TRACK_POSITION or TRACK_ANGLE
        qs = np.empty((len(targets), 7))
        tcps = np.empty((len(targets), 4, 4))
        for i, (target, grip) in enumerate(zip(targets, grips)):
            for name in FINGER_JOINTS:
                self.robot.set_joint(name, grip / 2)
            try:
                self.step(target, DT, soften=i < lead_in)
            except PlanError as error:
                k, tau = frame_of(i)
                raise PlanError(f"frame {k} (t = {tau:.2f} s): {error}") from None
            qs[i] = self.q()
            tcps[i] = self.tcp()
            if i >= lead_in - 1 and self.min_distance() < COLLISION_MARGIN - 1e-3:
                k, tau = frame_of(i)
                raise PlanError(f"frame {k} (t = {tau:.2f} s): the gripper collides{self._why()}")
            if i >= lead_in - 1:
                pos, ang = self.error(target)
                lagging = lagging + 1 if pos > TRACK_POSITION or ang > TRACK_ANGLE else 0
                start = i == lead_in - 1
                if lagging > (0 if start else LAG_SAMPLES) or pos > LAG_POSITION or ang > LAG_ANGLE:
                    k, tau = frame_of(i)
                    what = "the start pose" if start else "the target"
                    raise PlanError(f"frame {k} (t = {tau:.2f} s): the gripper cannot reach {what}: "
                                    f"{100 * pos:.1f} cm and {ang:.0f} deg away{self._why()}")
        return qs, tcps
