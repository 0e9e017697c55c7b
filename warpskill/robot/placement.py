"""Where the robot stands: a deterministic search of the base pose for the task.

Candidates are a grid of :class:`~warpskill.robot.model.Placement` s around the default
(scene-centre offsets :data:`OFFSETS_X` x :data:`OFFSETS_Y` in the base frame, yaws
:data:`YAWS` about the default's); one whose base would stand within :data:`BASE_CLEARANCE`
of a static box or the object's path is never taken. Each is scored on the task's key TCP
poses (pre-grasp, grasp, held samples, release, retreat; of the best-ranked grasp poses):

0. the whole held path (the wrist of each scored grasp pose in every frame from the grasp
   onset to the release) keeps :data:`REACH_MARGIN` inside the arm's reach: a candidate whose
   path comes closer to the limit ranks below every one that keeps it (the reconstruction's
   centimetres of error would otherwise lose the plan);
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
from warpskill.contract.skill import LayoutError
from warpskill.geometry import held_span, release_frame
from warpskill.robot.model import Placement, make_scene
from warpskill.robot.planner import COLLISION_MARGIN, Planner

__all__ = ["COMFORT_REACH", "NEAR_REACH", "OFFSETS_X", "OFFSETS_Y", "REACH", "REACH_MARGIN", "WRIST", "YAWS",
           "candidate_placements", "check_reach", "path_shortfall", "path_wrists", "rank_placements", "reach_excess"]

OFFSETS_X = (0.5, 0.42, 0.58, 0.34, 0.66)  # [m] scene centre ahead of the base
OFFSETS_Y = (0.0, -0.08, 0.08, -0.16, 0.16)  # [m] scene centre to the base's left
YAWS = (0.0, -20.0, 20.0, -40.0, 40.0)  # [deg] about the default yaw (the robot walks round the scene)
BASE_CLEARANCE = 0.2  # [m] the base's column stays this far from static boxes and the object's path
SHOULDER = 0.333  # [m] height of the Panda's shoulder above its base
WRIST = 0.21  # [m] wrist centre behind the TCP along the approach
REACH = 0.8  # [m] shoulder to wrist centre, fully stretched (a little less)
REACH_MARGIN = 0.05
"""[m] the whole held path (every frame from the grasp onset to the release, not only the key
poses) keeps its wrist points this far inside the workspace: :data:`REACH` of the shoulder,
:data:`NEAR_REACH` from the base's axis. A reconstruction's
sizes and path err by centimetres (on real held-out videos plans were lost 2.6 to 3.4 cm short
of a target near full stretch, where the arm also moves slowest): a placement whose path comes
closer to the reach limit ranks below every one that keeps the margin
(:func:`rank_placements`), and a new layout must keep it from some base placement
(:func:`check_reach`, which the layout sampler applies too)."""
NEAR_REACH = 0.25  # [m] the held path's wrist stays this far (plus REACH_MARGIN) from the base's axis: nearer, the arm folds onto itself (joint 4 at its limit)
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


def path_shortfall(base: np.ndarray, wrists: np.ndarray, margin: float = REACH_MARGIN) -> tuple[float, int]:
    """How far [m] the worst of ``wrists`` (M, 3) lies outside the workspace of the robot at ``base``
    (4, 4) shrunk by ``margin``: beyond ``REACH - margin`` of the shoulder, or nearer than
    ``NEAR_REACH + margin`` to the base's vertical axis; and its index. ``(0.0, -1)`` where
    every one keeps the margin."""
    if len(wrists) == 0:
        return 0.0, -1
    wrists = np.asarray(wrists)
    shoulder = base[:3, 3] + SHOULDER * base[:3, 2]
    excess = np.maximum(np.linalg.norm(wrists - shoulder, axis=1) - (REACH - margin),
                        NEAR_REACH + margin - np.linalg.norm(wrists[:, :2] - base[:2, 3], axis=1))
    worst = int(np.argmax(excess))
    return (float(excess[worst]), worst) if excess[worst] > 0.0 else (0.0, -1)


def path_wrists(recon: Reconstruction) -> tuple[np.ndarray, np.ndarray]:
    """The frames the robot holds (or pushes) the object in, from the grasp onset to the release
    (or the end), and the wrist point (F, 3) of a top grasp in each: :data:`WRIST` above the
    object's centre (the grasp pose is not chosen yet: the cheap, pose-free version of the path
    the placement search scores)."""
    span = held_span(recon.grasped)
    frames = np.arange(recon.num_frames) if span is None else np.arange(span[0], release_frame(recon.grasped) + 1)
    return frames, recon.object_pos[frames] + np.array([0.0, 0.0, WRIST])


def _path_cost(base: np.ndarray, paths: list[np.ndarray] | None) -> float:
    """The smallest :func:`path_shortfall` [m] over the grasp poses' wrist paths (0 without paths)."""
    if not paths:
        return 0.0
    return min(path_shortfall(base, wrists)[0] for wrists in paths)


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
                    *, count: int = 3, paths: list[np.ndarray] | None = None) -> list[Placement]:
    """Up to ``count`` placements for the task, best first (see the module doc).

    A placement from which some grasp pose's whole path keeps :data:`REACH_MARGIN` inside the
    reach ranks before every one from which none does (those follow by how far they come
    into the margin, then by cost); the default is kept without search only when it keeps it.

    Args:
        recon: the reconstruction (the scene; sizes as the robot handles them).
        keys: per grasp pose, the task's key TCP poses in the world.
        default: the grid's centre (default :class:`Placement`).
        paths: per grasp pose, the wrist points (M, 3) of its whole held path (None: keys only).
    """
    default = default or Placement()
    grid = candidate_placements(default)
    short0 = _path_cost(make_scene(recon, default).base, paths)
    cost0, good = _ik_score(recon, default, keys)
    if good and short0 == 0.0:
        return [default]
    proxies = []
    for p in grid[1:]:
        base = make_scene(recon, p).base
        if _base_blocked(recon, base):
            continue
        short = _path_cost(base, paths)
        proxies.append((short > 0.0, short, reach_excess(base, keys, COMFORT_REACH) + DEVIATION * _deviation(p, default),
                        p))
    proxies.sort(key=lambda item: item[:3])
    scored = [(short0 > 0.0, short0, cost0, default)]
    for short_of, short, _, p in proxies[:IK_CANDIDATES]:
        cost, good = _ik_score(recon, p, keys)
        scored.append((short_of, short, cost + DEVIATION * _deviation(p, default), p))
    # Within the margin: by cost; into it: the least shortfall first (centimetres matter there).
    scored.sort(key=lambda item: (item[0], item[1] if item[0] else 0.0, item[2]))
    return [item[3] for item in scored[:count]]


def check_reach(recon: Reconstruction, placement: Placement | None = None) -> None:
    """Refuse a scene the Panda cannot serve with :data:`REACH_MARGIN` to spare: the object's whole
    held path (:func:`path_wrists`: a top grasp's wrist, :data:`WRIST` above the centre, in every
    frame from the grasp onset to the release or the end) comes closer than the margin to the
    arm's :data:`REACH` from every candidate placement (or from ``placement``).

    A necessary condition, cheap enough to refuse a layout before any planning; the layout
    sampler (:func:`warpskill.export.layouts.layouts`) draws only layouts it accepts.

    Raises:
        LayoutError: one line naming the frame that comes closest to the limit from the best
            placement, by how much it misses the margin, and the margin.
    """
    frames, wrists = path_wrists(recon)
    best = (math.inf, -1)
    for p in candidate_placements() if placement is None else [placement]:
        short, worst = path_shortfall(make_scene(recon, p).base, wrists)
        if short == 0.0:
            return
        best = min(best, (short, worst))
    short, worst = best
    frame = int(frames[worst])
    x, y, _ = recon.object_pos[frame]
    where = "any base placement searched" if placement is None else "the given placement"
    raise LayoutError(f"layout refused: out of the Panda's reach: from {where} the object's held path runs "
                      f"{100 * short:.1f} cm into the {100 * REACH_MARGIN:.0f} cm margin kept inside the arm's "
                      f"{REACH:.2f} m reach and {NEAR_REACH:.2f} m from its base (frame {frame}, "
                      f"t = {recon.t[frame]:.2f} s, object at ({x:.2f}, {y:.2f}) m)", reason="out of reach")
