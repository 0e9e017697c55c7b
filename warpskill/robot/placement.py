"""Where the robot stands: a deterministic search of the base pose for the task.

Candidates are a grid of :class:`~warpskill.robot.model.Placement` s around the default
(scene-centre offsets :data:`OFFSETS_X` x :data:`OFFSETS_Y` in the base frame, yaws
:data:`YAWS` about the default's); one whose base would stand within :data:`BASE_CLEARANCE`
of a static box or the object's path is never taken. Each is scored on the task's key TCP
poses (pre-grasp, grasp, held samples, release, retreat; of the best-ranked grasp poses):

1. a cheap geometric proxy for every candidate: how far each key's wrist point lies beyond
   :data:`COMFORT_REACH` from the shoulder (short of full stretch, where the arm moves slowly
   and lags a fast demonstration), or inside the column above the base;
2. placo static IK (chained key to key, few iterations) for the default and the best
   :data:`IK_CANDIDATES` of the proxy: the summed reach errors, and the joint-limit and
   collision margins, plus a small cost for moving away from the default.

The default is kept without further search when its IK check passes with comfortable
margins. :func:`rank_placements` returns the candidates best first; the retargeting runs
its full plan on the first few.
"""

from __future__ import annotations

import math

import numpy as np

from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.skill import HELD, LayoutError
from warpskill.robot.model import Placement, make_scene
from warpskill.robot.planner import COLLISION_MARGIN, Planner

__all__ = ["COMFORT_REACH", "OFFSETS_X", "OFFSETS_Y", "YAWS", "candidate_placements", "check_reach", "rank_placements",
           "reach_excess"]

OFFSETS_X = (0.5, 0.42, 0.58, 0.34, 0.66)  # [m] scene centre ahead of the base
OFFSETS_Y = (0.0, -0.08, 0.08, -0.16, 0.16)  # [m] scene centre to the base's left
YAWS = (0.0, -20.0, 20.0, -40.0, 40.0)  # [deg] about the default yaw (the robot walks round the scene)
BASE_CLEARANCE = 0.2  # [m] the base's column stays this far from static boxes and the object's path
SHOULDER = 0.333  # [m] height of the Panda's shoulder above its base
WRIST = 0.21  # [m] wrist centre behind the TCP along the approach
REACH = 0.8  # [m] shoulder to wrist centre, fully stretched (a little less)
COMFORT_REACH = 0.7  # [m] placements are ranked by the keys beyond this: near full stretch the arm is slow
COLUMN = 0.15  # [m] the wrist cannot come closer than this to the base's vertical axis
IK_CANDIDATES = 6  # candidates checked with IK after the proxy
REACHED = 0.005  # [m] a key pose counts as reached within this ...
REACHED_ANGLE = 4.0  # [deg] ... and this
GOOD_JOINT_MARGIN = 0.15  # [rad] the default is kept when every key pose has this joint margin ...
GOOD_CLEARANCE = 0.008  # [m] ... and this clearance
DEVIATION = 0.1  # cost per metre (and per radian) away from the default placement


def candidate_placements(default: Placement | None = None) -> list[Placement]:
    """The grid around ``default``, nearest first (the default itself first)."""
    default = default or Placement()
    x0, y0 = default.offset
    grid = []
    for dx in OFFSETS_X:
        for dy in OFFSETS_Y:
            for dyaw in YAWS:
                p = Placement(offset=(dx + x0 - 0.5, dy + y0), yaw=default.yaw + math.radians(dyaw))
                grid.append((_deviation(p, default), p))
    grid.sort(key=lambda item: item[0])
    return [p for _, p in grid]


def _deviation(p: Placement, default: Placement) -> float:
    return float(np.hypot(p.offset[0] - default.offset[0], p.offset[1] - default.offset[1])
                 + abs(p.yaw - default.yaw))


def _base_blocked(recon: Reconstruction, base: np.ndarray) -> bool:
    """Whether the base's column would stand on a static box or in the object's path."""
    xy = base[:2, 3]
    if len(recon.object_pos) and np.min(np.linalg.norm(recon.object_pos[:, :2] - xy, axis=1)) < BASE_CLEARANCE:
        return True
    for k in range(recon.num_static):
        local = recon.static_rot[k].T @ np.array([*(xy - recon.static_pos[k, :2]), 0.0])
        gap = np.maximum(np.abs(local[:2]) - recon.static_size[k, :2] / 2, 0.0)
        if np.linalg.norm(gap) < BASE_CLEARANCE:
            return True
    return False


def reach_excess(base: np.ndarray, keys: list[list[np.ndarray]], reach: float = REACH) -> float:
    """Reach excess [m] of the key poses (4, 4) from ``base``, the best grasp pose's (the geometric proxy).

    0 where some grasp pose's keys all lie within ``reach`` (default :data:`REACH`, the
    arm's) of the shoulder, outside the :data:`COLUMN` above the base; more than 0 for none.
    """
    shoulder = base[:3, 3] + SHOULDER * base[:3, 2]
    best = math.inf
    for pose_keys in keys:
        excess = 0.0
        for T in pose_keys:
            wrist = T[:3, 3] - WRIST * T[:3, 2]
            excess += max(0.0, float(np.linalg.norm(wrist - shoulder)) - reach)
            excess += max(0.0, COLUMN - float(np.linalg.norm(wrist[:2] - base[:2, 3])))
        best = min(best, excess)
    return best


def _ik_score(recon: Reconstruction, placement: Placement, keys: list[list[np.ndarray]]) -> tuple[float, bool]:
    """(cost, comfortable) of the key poses with placo at ``placement``; the best grasp pose's."""
    planner = Planner(make_scene(recon, placement))
    best, comfortable = math.inf, False
    for pose_keys in keys:
        cost, good, q = 0.0, True, None
        for j, T in enumerate(pose_keys):
            q, pos, ang, margin, clearance = planner.reach(T, q, iterations=60 if j == 0 else 25)
            reached = pos <= REACHED and ang <= REACHED_ANGLE and clearance >= COLLISION_MARGIN - 1e-3
            cost += 20.0 * max(0.0, pos - REACHED) + 0.05 * max(0.0, ang - REACHED_ANGLE) + (0.0 if reached else 1.0)
            cost += 0.5 * max(0.0, GOOD_JOINT_MARGIN - margin) + 5.0 * max(0.0, GOOD_CLEARANCE - clearance)
            good = good and reached and margin >= GOOD_JOINT_MARGIN and clearance >= GOOD_CLEARANCE
            if cost > best:
                break
        if cost < best:
            best, comfortable = cost, good
        if good:  # comfortable with this pose: the placement needs no other
            break
    return best, comfortable


def rank_placements(recon: Reconstruction, keys: list[list[np.ndarray]], default: Placement | None = None,
                    *, count: int = 3) -> list[Placement]:
    """Up to ``count`` placements for the task, best first (see the module doc).

    Args:
        recon: the reconstruction (the scene; sizes as the robot handles them).
        keys: per grasp pose, the task's key TCP poses in the world.
        default: the grid's centre (default :class:`Placement`).
    """
    default = default or Placement()
    grid = candidate_placements(default)
    cost0, good = _ik_score(recon, default, keys)
    if good:
        return [default]
    proxies = []
    for p in grid[1:]:
        base = make_scene(recon, p).base
        if _base_blocked(recon, base):
            continue
        proxies.append((reach_excess(base, keys, COMFORT_REACH) + DEVIATION * _deviation(p, default), p))
    proxies.sort(key=lambda item: item[0])
    scored = [(cost0, default)]
    for _, p in proxies[:IK_CANDIDATES]:
        cost, good = _ik_score(recon, p, keys)
        scored.append((cost + DEVIATION * _deviation(p, default), p))
    scored.sort(key=lambda item: item[0])
    return [p for _, p in scored[:count]]


def check_reach(recon: Reconstruction, placement: Placement | None = None) -> None:
    """Refuse a scene the Panda cannot serve: the object where the hand takes it and where it lets go
    (or at the end) out of reach from every candidate placement (or from ``placement``).

    A point counts as reachable when the wrist of a top grasp (:data:`WRIST` above it) lies
    within :data:`REACH` of the shoulder: a necessary condition, cheap enough to refuse a
    layout before any planning.

    Raises:
        LayoutError: one line naming the points and the reach.
    """
    held = np.flatnonzero(recon.grasped > HELD)
    frames = [int(held[0]), min(int(held[-1]) + 1, recon.num_frames - 1)] if len(held) else [0, recon.num_frames - 1]
    wrists = recon.object_pos[frames] + np.array([0.0, 0.0, WRIST])
    for p in candidate_placements() if placement is None else [placement]:
        base = make_scene(recon, p).base
        shoulder = base[:3, 3] + SHOULDER * base[:3, 2]
        if np.all(np.linalg.norm(wrists - shoulder, axis=1) <= REACH):
            return
    (x0, y0), (x1, y1) = recon.object_pos[frames, :2]
    where = "any base placement searched" if placement is None else "the given placement"
    raise LayoutError(f"layout refused: out of the Panda's reach: from {where} the object's grasp at "
                      f"({x0:.2f}, {y0:.2f}) m and its release at ({x1:.2f}, {y1:.2f}) m are not both within "
                      f"{REACH:.2f} m of the shoulder")
