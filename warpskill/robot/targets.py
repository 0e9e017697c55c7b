"""The TCP targets of a plan: from home onto the demonstrated path, through the contact, and away.

The plan, sampled every :data:`~warpskill.robot.planner.DT`:

1. lead-in (:data:`LEAD_IN` s, reconstruction time 0): from the home configuration's TCP
   pose up over the join pose and down onto it (position min-jerk, orientation slerped to
   the grasp's), passing at least :data:`LEAD_RISE` over the object's top (where that is
   higher than home, the TCP rises in the first half of the move: the arm would otherwise
   sweep through a tall object's top before the contact); the join pose is where the robot
   takes up the demonstrated hand path, at most :data:`FOLLOW_TIME` s before the pre-grasp
   and never further than :data:`FOLLOW_RADIUS` from it (the free-hand motion far from the
   object is not followed) nor where the open fingers come near the object (the
   reconstructed hand may pass through it or close beside it); the robot waits there until
   the demonstration reaches it;
2. approach: the demonstrated tip path, shifted so that it ends at the pre-grasp pose
   (:data:`PREGRASP` back along the approach), then a straight move onto the grasp pose
   at the onset, never faster than :data:`APPROACH_TIME` (without ``follow_hand``, the
   join pose is the pre-grasp itself);
3. grasp: the gripper closes (``CLOSE_TIME`` s, the arm waits; the fingers start
   :data:`CLOSE_DELAY` after the arm arrives);
4. hold: a carried object follows its reconstructed path upright, in its orientation at
   the grasp, at least :data:`CLEARANCE` above its support; a push follows the object's
   horizontal displacement at the push height;
5. release: the gripper opens (``OPEN_TIME`` s) and the TCP backs off along the approach.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from warpskill.contract.reconstruction import Reconstruction
from warpskill.geometry import cuboid_corners, min_jerk
from warpskill.robot.grasps import GraspPose
from warpskill.robot.model import FINGER_SPEED, MAX_OPENING, Scene
from warpskill.robot.plan import CLOSE_TIME, OPEN_TIME
from warpskill.robot.planner import DT
from warpskill.robot.skill_layout import ONTO_INSET

__all__ = [
    "LEAD_IN",
    "PREGRASP",
    "Targets",
    "hold_pose",
    "key_targets",
    "lift_clear",
    "onto_release",
    "plan_targets",
    "pose_matrix",
    "support_height",
    "translate",
]

LEAD_IN = 2.5  # [s] from home to the join pose (the last LEAD_SETTLE of it still)
LEAD_SETTLE = 0.3  # [s]
LEAD_RISE = 0.1  # [m] the lead-in passes this high above the join pose
FOLLOW_TIME = 0.8  # [s] the demonstrated hand path is followed at most this long before the pre-grasp ...
FOLLOW_RADIUS = 0.2  # [m] ... and only where it stays this close to the pre-grasp
OBJECT_CLEARANCE = 0.02  # [m] ... and with the open fingers this far outside the object
FINGER_LENGTH = 0.045  # [m] of the Panda's fingers, from the tips (at the TCP) back to the hand
PREGRASP = 0.08  # [m] pre-grasp stand-off along the approach
APPROACH_TIME = 0.6  # [s] from the pre-grasp to the grasp pose
RETREAT = 0.10  # [m] back-off along the approach after the release
RETREAT_TIME = 0.6  # [s]
SETTLE = 0.5  # [s] still time at the end
CLEARANCE = 0.003  # [m] a carried object is kept this far above its support
ONTO_CLEARANCE = 0.005
"""[m] a put onto lets go with the carried object's bottom this far above the static box's top:
released lower, the fingers would press it into the top; higher, it drops and may bounce off."""
HOLD_KEYS = 3  # held-object samples among the key targets
CLOSE_DELAY = 0.2
"""[s] the gripper starts closing this long after the arm reaches the grasp pose (within
``CLOSE_TIME``): the position-controlled arm lags the plan by about 6 mm there, and fingers
closed at once pinched above a 1 cm card and came to rest on its top."""


@dataclasses.dataclass
class Targets:
    """Plan samples: times, reconstruction times, TCP targets, gripper openings and the events' times."""

    times: list
    taus: list
    targets: list
    grips: list
    lead_in: int
    start_time: float
    grasp_time: float
    release_time: float

    def add(self, tau: float, T: np.ndarray, grip: float) -> None:
        """Append a sample one planner step (:data:`~warpskill.robot.planner.DT`) after the last:
        reconstruction time ``tau`` [s], TCP target ``T`` (4, 4), gripper opening ``grip`` [m]."""
        self.times.append(len(self.times) * DT)
        self.taus.append(tau)
        self.targets.append(T)
        self.grips.append(grip)


def pose_matrix(pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """The (4, 4) pose of rotation ``rot`` at ``pos``."""
    T = np.eye(4)
    T[:3, :3] = rot
    T[:3, 3] = pos
    return T


def translate(x: float, y: float, z: float) -> np.ndarray:
    """The (4, 4) translation by (x, y, z)."""
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def support_height(scene: Scene, T_obj: np.ndarray, size: np.ndarray) -> float:
    """Height [m] of the surface under the object at ``T_obj``: the table or a static box's top."""
    floor = 0.0
    radius = 0.5 * min(size[0], size[1])
    for k in range(len(scene.static_pos)):
        local = scene.static_rot[k].T @ (T_obj[:3, 3] - scene.static_pos[k])
        if np.all(np.abs(local[:2]) < scene.static_size[k, :2] / 2 + radius):
            floor = max(floor, scene.static_pos[k, 2] + scene.static_size[k, 2] / 2)
    return floor


def lift_clear(T_obj: np.ndarray, size: np.ndarray, floor: float) -> np.ndarray:
    """``T_obj`` raised so that the cuboid's lowest corner is at least :data:`CLEARANCE` above ``floor``."""
    corners = cuboid_corners(T_obj[:3, 3], T_obj[:3, :3], size)
    lift = floor + CLEARANCE - corners[:, 2].min()
    if lift > 0:
        T_obj = T_obj.copy()
        T_obj[2, 3] += lift
    return T_obj


def onto_release(scene: Scene, T_off: np.ndarray, size: np.ndarray, static: int = 0) -> np.ndarray:
    """The put-onto release pose of the object (pose ``T_off`` (4, 4) at the demonstrated release,
    edge lengths ``size`` (3,): the carried object's own) on static box ``static``'s top.

    The centre is moved horizontally into the top (:data:`~warpskill.robot.skill_layout.ONTO_INSET` inside its edges, in the
    box's frame) and vertically so that the object's lowest corner is :data:`ONTO_CLEARANCE`
    above the box's reconstructed top; the orientation is kept.
    """
    R, c, half_box = scene.static_rot[static], scene.static_pos[static], scene.static_size[static] / 2
    local = R.T @ (T_off[:3, 3] - c)
    limit = np.maximum(half_box[:2] - ONTO_INSET, 0.5 * half_box[:2])
    local[:2] = np.clip(local[:2], -limit, limit)
    placed = T_off.copy()
    placed[:3, 3] = c + R @ local
    top = float(cuboid_corners(c, R, scene.static_size[static])[:, 2].max())
    bottom = float(cuboid_corners(placed[:3, 3], placed[:3, :3], size)[:, 2].min())
    placed[2, 3] += top + ONTO_CLEARANCE - bottom
    return placed


def _fingers_near_object(recon: Reconstruction, T: np.ndarray, opening: float) -> bool:
    """Whether the open gripper at TCP pose ``T`` (4, 4), fingers ``opening`` [m] apart, comes
    within :data:`OBJECT_CLEARANCE` of the object where it rests (its first frame).

    The reconstructed hand may pass through the object before the contact (the physics lets
    it), or close beside it (a hand is narrower than an open gripper): the gripper following
    that path would knock the object over. Each finger is taken as the segment from its tip
    (at the TCP's height) :data:`FINGER_LENGTH` back along the approach, on either side of the
    TCP along the closing axis (``T``'s y); the TCP itself is the segment's middle point.
    """
    across = np.linspace(-0.5, 0.5, 5)[:, None] * opening * T[:3, 1]  # (5, 3): the finger line through the TCP
    up = np.array([0.0, FINGER_LENGTH])[:, None, None] * -T[:3, 2]  # (2, 1, 3): tip and top of the fingers
    points = (T[:3, 3] + across + up).reshape(-1, 3)
    local = (points - recon.object_pos[0]) @ recon.object_rot[0]
    return bool(np.any(np.all(np.abs(local) < 0.5 * recon.object_size + OBJECT_CLEARANCE, axis=1)))


def _interp_path(path: np.ndarray, t: np.ndarray, tau: float) -> np.ndarray:
    """The point (3,) of ``path`` (T, 3) sampled at times ``t`` at time ``tau`` (linear)."""
    return np.array([np.interp(tau, t, path[:, i]) for i in range(3)])


def _slerp(A: np.ndarray, B: np.ndarray, s: float) -> np.ndarray:
    """Rotation a fraction ``s`` of the way from ``A`` to ``B`` (3, 3)."""
    R = A.T @ B
    angle = math.acos(float(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))
    if angle < 1e-6:
        return B.copy() if s >= 1.0 else A.copy()
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if np.linalg.norm(axis) < 1e-6:  # a half turn: the axis from the symmetric part
        axis = np.sqrt(np.clip((np.diag(R) + 1.0) / 2.0, 0.0, None))
    axis /= np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    a = s * angle
    return A @ (np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K)


def hold_pose(recon: Reconstruction, scene: Scene, pose: GraspPose, k_on: int, k_off: int | None, tau: float,
              release_shift: np.ndarray) -> np.ndarray:
    """The TCP target while holding (or pushing) the object at reconstruction time ``tau``."""
    t_on = float(recon.t[k_on])
    t_off = float(recon.t[k_off]) if k_off is not None else None
    T_on = pose_matrix(recon.object_pos[k_on], recon.object_rot[k_on])
    T_obj = pose_matrix(_interp_path(recon.object_pos, recon.t, tau), T_on[:3, :3])
    if t_off is not None:
        T_obj[:3, 3] += release_shift * float(np.clip((tau - t_on) / max(t_off - t_on, 1e-9), 0.0, 1.0))
    if pose.kind == "push":
        T = T_on @ pose.pose
        T[:2, 3] += T_obj[:2, 3] - T_on[:2, 3]
        return T
    T_obj = lift_clear(T_obj, recon.object_size, support_height(scene, T_obj, recon.object_size))
    return T_obj @ pose.pose


def _grasp_frames(recon: Reconstruction, pose: GraspPose, k_on: int):
    """The grasp pose G, where a hook comes down G_down, and the pre-grasp, in the world at the onset."""
    G = pose_matrix(recon.object_pos[k_on], recon.object_rot[k_on]) @ pose.pose
    approach = G[:3, 2]
    outward = approach - approach[2] * np.array([0.0, 0.0, 1.0])
    G_down = G.copy()
    G_down[:3, 3] += pose.standoff * outward / max(np.linalg.norm(outward), 1e-9)
    return G, G_down, G_down @ translate(0, 0, -PREGRASP)


def key_targets(recon: Reconstruction, scene: Scene, pose: GraspPose, k_on: int, k_off: int | None,
                release_shift: np.ndarray | None = None) -> list[np.ndarray]:
    """The task's key TCP poses for ``pose``: pre-grasp, grasp, held samples, release, retreat."""
    shift = np.zeros(3) if release_shift is None else release_shift
    _, G_down, pregrasp = _grasp_frames(recon, pose, k_on)
    t_on = float(recon.t[k_on])
    t_end = float(recon.t[k_off]) if k_off is not None else float(recon.t[-1])
    keys = [pregrasp, G_down]
    for s in np.linspace(0.0, 1.0, HOLD_KEYS + 1)[1:]:
        keys.append(hold_pose(recon, scene, pose, k_on, k_off, t_on + s * (t_end - t_on), shift))
    if k_off is not None:
        retreat = keys[-1].copy()
        retreat[:3, 3] -= RETREAT * retreat[:3, 2]
        keys.append(retreat)
    return keys


def plan_targets(recon: Reconstruction, scene: Scene, pose: GraspPose, k_on: int, k_off: int | None, slow: float,
                 release_shift: np.ndarray, home_tcp: np.ndarray, follow_hand: bool = True) -> Targets:
    """The plan's samples (see the module doc) for ``pose``.

    The demonstration is played ``slow`` times slower than recorded; the carried object
    drifts linearly by ``release_shift`` (3,) [m] from the grasp to the release;
    ``home_tcp`` is the TCP pose of the home configuration. Without ``follow_hand`` the
    robot joins the demonstration at the pre-grasp pose.
    """
    step = DT / slow
    t_on = float(recon.t[k_on])
    t_off = float(recon.t[k_off]) if k_off is not None else None
    t_end = float(recon.t[-1])
    G, G_down, pregrasp = _grasp_frames(recon, pose, k_on)
    approach = G[:3, 2]
    app_time = min(APPROACH_TIME, 0.5 * t_on) if t_on > 0 else 0.0
    t_pre = t_on - app_time
    path_shift = pregrasp[:3, 3] - _interp_path(recon.hand_pos, recon.t, t_pre)  # the hand path ends at the pre-grasp
    t_join = t_pre
    opening = 0.0 if pose.kind == "push" else min(MAX_OPENING, pose.width + 0.02)
    if follow_hand:  # back along the demonstrated path while it stays near the pre-grasp and the fingers clear of the object
        for tau in np.arange(t_pre, max(0.0, t_pre - FOLLOW_TIME) - 1e-9, -DT):
            T = G.copy()
            T[:3, 3] = _interp_path(recon.hand_pos, recon.t, tau) + path_shift
            if np.linalg.norm(T[:3, 3] - pregrasp[:3, 3]) > FOLLOW_RADIUS or _fingers_near_object(recon, T, opening):
                break
            t_join = float(tau)
    close_ramp = max(opening / (2 * FINGER_SPEED), DT)
    out = Targets([], [], [], [], 0, 0.0, 0.0, math.nan)

    def approach_target(tau: float) -> np.ndarray:  # the demonstrated path, until the pre-grasp
        T = G.copy()
        T[:3, 3] = _interp_path(recon.hand_pos, recon.t, float(np.clip(tau, t_join, t_pre))) + path_shift
        return T

    _lead_in(out, recon, approach_target(t_join), home_tcp, opening)
    out.start_time = len(out.times) * DT
    for tau in np.arange(0.0, t_pre, step):
        out.add(float(tau), approach_target(float(tau)), opening)
    # The straight move onto the grasp takes APPROACH_TIME at least, also where the demonstration
    # leaves less (a contact from the first frames): the reconstruction's time then runs slower.
    n_app = max(int(round(APPROACH_TIME / DT)), int(round(app_time / step)))
    for i in range(n_app):
        s = min_jerk(np.array((i + 1) / n_app))
        T = G.copy()
        T[:3, 3] = (1 - s) * pregrasp[:3, 3] + s * G_down[:3, 3]
        out.add(t_pre + (t_on - t_pre) * i / n_app, T, opening)
    out.grasp_time = len(out.times) * DT
    n_close = int(round(CLOSE_TIME / DT))
    for i in range(n_close):
        T = G.copy()
        T[:3, 3] = G_down[:3, 3] + min_jerk(np.array((i + 1) / n_close)) * (G[:3, 3] - G_down[:3, 3])
        out.add(t_on, T, opening * float(np.clip(1.0 - (i * DT - CLOSE_DELAY) / close_ramp, 0.0, 1.0)))

    def hold_target(tau: float) -> np.ndarray:
        return hold_pose(recon, scene, pose, k_on, k_off, tau, release_shift)

    hold_end = t_off if t_off is not None else t_end
    for tau in np.arange(t_on, hold_end, step):
        out.add(float(tau), hold_target(float(tau)), 0.0)
    if t_off is None:
        last = hold_target(t_end)
        for _ in range(int(round(SETTLE / DT))):
            out.add(t_end, last, 0.0)
        return out
    out.release_time = len(out.times) * DT
    _release(out, hold_target(t_off), approach, t_off, t_end, step, opening, close_ramp)
    return out


def _lead_in(out: Targets, recon: Reconstruction, join: np.ndarray, home_tcp: np.ndarray, opening: float) -> None:
    """Append the lead-in: from the home TCP pose ``home_tcp`` (4, 4) up over the object and onto
    ``join`` (4, 4), the demonstrated path's first followed pose, in :data:`LEAD_IN`."""
    above = join.copy()
    above[2, 3] = max(join[2, 3] + LEAD_RISE, min(home_tcp[2, 3], join[2, 3] + 2 * LEAD_RISE))
    object_top = float(cuboid_corners(recon.object_pos[0], recon.object_rot[0], recon.object_size)[:, 2].max())
    over_object = object_top + LEAD_RISE
    rise_first = over_object > max(above[2, 3], home_tcp[2, 3])
    above[2, 3] = max(above[2, 3], over_object)
    n_lead = int(round(LEAD_IN / DT))
    n_move = n_lead - int(round(LEAD_SETTLE / DT))
    n_up = int(0.65 * n_move)
    for i in range(n_lead):
        T = join.copy()
        if i < n_up:
            s = float(min_jerk(np.array((i + 1) / n_up)))
            T[:3, :3] = _slerp(home_tcp[:3, :3], join[:3, :3], s)
            T[:3, 3] = (1 - s) * home_tcp[:3, 3] + s * above[:3, 3]
            if rise_first:  # up to the pass height in the first half of the move
                rise = float(min_jerk(np.array(min(1.0, 2.0 * (i + 1) / n_up))))
                T[2, 3] = (1 - rise) * home_tcp[2, 3] + rise * above[2, 3]
        elif i < n_move:
            s = float(min_jerk(np.array((i + 1 - n_up) / (n_move - n_up))))
            T[:3, 3] = (1 - s) * above[:3, 3] + s * join[:3, 3]
        out.add(0.0, T, opening)
    out.lead_in = n_lead


def _release(out: Targets, placed: np.ndarray, approach: np.ndarray, t_off: float, t_end: float, step: float,
             opening: float, close_ramp: float) -> None:
    """Append the release at ``placed`` (4, 4) (the gripper opens) and the retreat along ``approach`` (3,),
    the grasp's approach direction."""
    for i in range(int(round(OPEN_TIME / DT))):
        out.add(t_off, placed, opening * min(1.0, (i * DT) / close_ramp))
    for tau in np.arange(t_off, t_end + SETTLE, step):
        s = min_jerk(np.array((tau - t_off) / RETREAT_TIME))
        T = placed.copy()
        T[:3, 3] -= s * RETREAT * approach
        out.add(float(min(tau, t_end)), T, opening)
