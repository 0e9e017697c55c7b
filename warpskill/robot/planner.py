"""The placo differential-IK planner of one robot scene: a TCP frame task under hard limits.

:class:`Planner` wraps a placo ``RobotWrapper`` (the Panda's collision primitives with the
table and the static cuboids fixed to its base, visuals stripped: loading no meshes keeps
a planner's construction at a few milliseconds) and a ``KinematicsSolver``: the TCP frame
task, joint position limits (:data:`LIMIT_MARGIN` inside) and velocity limits
(:data:`VELOCITY_SCALE` of the URDF's), self-collision and table/static avoidance (hard,
:data:`COLLISION_MARGIN`), a light posture task towards the home configuration.
"""

from __future__ import annotations

import contextlib
import ctypes
import json
import math
import os
import re
import sys
import tempfile

import numpy as np

from warpskill.robot.model import (
    ARM_JOINTS,
    FINGER_JOINTS,
    HOME_Q,
    MAX_OPENING,
    TCP_FRAME,
    Scene,
    collision_pairs,
    planner_urdf,
)
from warpskill.robot.plan import PlanError

__all__ = [
    "COLLISION_MARGIN",
    "DT",
    "LIMIT_MARGIN",
    "TRACK_ANGLE",
    "TRACK_POSITION",
    "Planner",
    "quiet_stdout",
    "rotation_error_deg",
]

DT = 0.02  # [s] plan sample period
VELOCITY_SCALE = 0.9  # plan within this fraction of the URDF joint speed limits
LIMIT_MARGIN = 0.02  # [rad] plan this far inside the joint limits
COLLISION_MARGIN = 0.005  # [m] smallest planned distance between checked bodies
SOFT_COLLISION_WEIGHT = 100.0  # weight of the collision constraint when a start must be softened
TRACK_POSITION = 0.01  # [m] largest TCP position error accepted
TRACK_ANGLE = 8.0  # [deg] largest TCP orientation error accepted
LAG_SAMPLES = 10  # the TCP may lag further behind a fast target for this many samples (0.2 s) ...
LAG_POSITION = 0.025  # [m] ... but never by more than this
LAG_ANGLE = 15.0  # [deg] ... or this
CONVERGED_POSITION = 2e-4  # [m] a static IK stops this close to its target ...
CONVERGED_ANGLE = 0.2  # [deg] ... and this
STALLED = 1e-4  # [rad] ... or when no joint moved more than this in 5 steps


@contextlib.contextmanager
def quiet_stdout():
    """Silence C-level stdout and stderr (placo reports self-collisions of the neutral pose when loading)."""
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


def _at(error: PlanError, sample: int, kind: str) -> PlanError:
    """``error`` marked with the plan sample it happened at and its kind (reach, collision, infeasible)."""
    error.sample = sample
    error.kind = kind
    return error


def rotation_error_deg(A: np.ndarray, B: np.ndarray) -> float:
    c = (np.trace(A.T @ B) - 1.0) / 2.0
    return math.degrees(math.acos(float(np.clip(c, -1.0, 1.0))))


class Planner:
    """placo robot + kinematics solver for one scene."""

    def __init__(self, scene: Scene):
        import placo  # optional extra: robot

        self.placo = placo
        with quiet_stdout():
            self.robot = placo.RobotWrapper("", 0, re.sub(r"<visual>.*?</visual>", "", planner_urdf(scene), flags=re.DOTALL))
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
        return float(np.linalg.norm(T[:3, 3] - target[:3, 3])), rotation_error_deg(T[:3, :3], target[:3, :3])

    def static_ik(self, target: np.ndarray, q0: np.ndarray | None = None, iterations: int = 150):
        """Configuration reaching ``target`` from ``q0`` (home) or (None, why)."""
        self.set_q(HOME_Q if q0 is None else q0, MAX_OPENING)
        self.solver.enable_velocity_limits(False)
        try:
            self._converge(target, iterations)
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

    def _converge(self, target: np.ndarray, iterations: int) -> None:
        """Static IK steps towards ``target``: at most ``iterations``, fewer once on it or stalled."""
        previous = self.q()
        for i in range(iterations):
            self.step(target, 0.05, soften=True)
            if i % 5 == 4:
                pos, ang = self.error(target)
                q = self.q()
                if (pos < CONVERGED_POSITION and ang < CONVERGED_ANGLE) or np.abs(q - previous).max() < STALLED:
                    return
                previous = q

    def joint_margin(self) -> float:
        """Smallest distance [rad] of an arm joint to its planning limit."""
        margin = math.inf
        for name in ARM_JOINTS:
            lo, hi = self.robot.get_joint_limits(name)
            v = self.robot.get_joint(name)
            margin = min(margin, v - lo, hi - v)
        return float(margin)

    def reach(self, target: np.ndarray, q0: np.ndarray | None = None, iterations: int = 40):
        """Static IK towards ``target`` from ``q0`` (home) that never fails: the cheap check of a pose.

        Returns:
            ``(q (7,), position error [m], angle error [deg], joint margin [rad], clearance [m])``;
            an infeasible QP counts as a 1 m position error.
        """
        self.set_q(HOME_Q if q0 is None else q0, MAX_OPENING)
        self.solver.enable_velocity_limits(False)
        try:
            self._converge(target, iterations)
        except PlanError:
            return self.q(), 1.0, 180.0, 0.0, -1.0
        finally:
            self.solver.enable_velocity_limits(True)
        pos, ang = self.error(target)
        return self.q(), pos, ang, self.joint_margin(), self.min_distance()

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
                raise _at(PlanError(f"frame {k} (t = {tau:.2f} s): {error}"), i, "infeasible") from None
            qs[i] = self.q()
            tcps[i] = self.tcp()
            if i >= lead_in - 1 and self.min_distance() < COLLISION_MARGIN - 1e-3:
                k, tau = frame_of(i)
                raise _at(PlanError(f"frame {k} (t = {tau:.2f} s): the gripper collides{self._why()}"), i, "collision")
            if i >= lead_in - 1:
                pos, ang = self.error(target)
                lagging = lagging + 1 if pos > TRACK_POSITION or ang > TRACK_ANGLE else 0
                start = i == lead_in - 1
                if lagging > (0 if start else LAG_SAMPLES) or pos > LAG_POSITION or ang > LAG_ANGLE:
                    k, tau = frame_of(i)
                    what = "the start pose" if start else "the target"
                    raise _at(PlanError(f"frame {k} (t = {tau:.2f} s): the gripper cannot reach {what}: "
                                        f"{100 * pos:.1f} cm and {ang:.0f} deg away{self._why()}"), i, "reach")
        return qs, tcps
