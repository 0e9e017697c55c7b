"""Predefined grasp and push poses of the Panda gripper on a cuboid, ranked against a demonstration.

A pose is the tool-centre-point (TCP) frame in the cuboid's frame: TCP +z is the approach
direction (into the object), TCP +y the direction the fingers open along. Families, with
the cuboid's faces named by the world direction they face at the contact onset:

- ``top_*``: from above, fingers across a horizontal edge length; ``top_*_shallow`` holds
  the top :data:`SHALLOW_DEPTH` only, so the hand stays above a taller neighbour when the
  object is set down beside it;
- ``edge_*``: 45 degrees down onto the top edge of a side face, fingers across that face;
- ``side_*``: horizontally onto a side face, fingers across it;
- ``rim_*`` (open-topped objects: a cup, a mug, a bowl, of any width): from above onto the
  rim of a side face's wall, fingers closing across the wall (:data:`RIM_WALL` thick), one
  inside the vessel and one outside, :func:`rim_depth` below the rim;
- ``push_*``: closed fingers against a side face, 30, 45 or 60 degrees down, at the
  demonstrated height;
- ``hook_*`` (pulls of cuboids too wide to grasp): closed fingers reach over the cuboid from
  the demonstrated side, 60 or 75 degrees down, and hook behind the far face at
  :data:`HOOK_HEIGHT`; they come down :attr:`GraspPose.standoff` outside that face (so
  the straight approach clears the top edge) and move onto it while the gripper would close.

Grasps need the edge length between the fingers to fit the opening (:data:`MAX_OPENING`
less a margin), rims only a wall tall enough for the pads (:func:`rim_fits`); pushes need none.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from warpskill.robot.model import MAX_OPENING, RIM_WALL

FIT_MARGIN = 0.006  # [m] the object must be this much narrower than the full opening
TOP_DEPTH = 0.03  # [m] how far below the top face the finger pads' centre goes
SHALLOW_DEPTH = 0.015  # [m] the same for a shallow top grasp
EDGE_DEPTH = 0.025  # [m] how far past the top edge (along the approach) the pads' centre goes
SIDE_DEPTH = 0.03  # [m] how far into a side face the pads' centre goes
FINGERTIP_BELOW_TCP = 0.0095  # [m] the finger pads end this far beyond the TCP along the approach (panda.urdf's pad box)
TABLE_CLEARANCE = 0.006  # [m] a top grasp's fingertips stay this far above the object's bottom (planner: 5 mm)
MIN_PUSH_HEIGHT = 0.02  # [m] lowest TCP height above the object's bottom for a push (the fingertips clear the table)
PUSH_BELOW_TOP = 0.005  # [m] a push's TCP stays this far below the top face (thin objects: pressed at their top edge)
HOOK_HEIGHT = 0.02  # [m] TCP height above the object's bottom of a hook (low: lagging fingers ride over a higher one)
HOOK_OFFSET = 0.012  # [m] TCP outside the hooked face: the closed fingers' half thickness
HOOK_CLEARANCE = 0.015  # [m] the approaching fingertips pass this far outside the hooked face's top edge
RIM_DEPTH = 0.025  # [m] how far below the rim the pads' centre goes (less on a low vessel: rim_depth)
MIN_RIM_DEPTH = 0.01  # [m] the least of it: a lower vessel's rim is not grasped
SLANT_WEIGHT = 2.0  # [deg per deg] cost of a pressing pose's horizontal slant to the push direction


@dataclasses.dataclass(frozen=True)
class GraspPose:
    """One predefined pose of the gripper on the cuboid.

    Attributes:
        name: family and face, e.g. ``top_x``, ``edge_-y``, ``push_+x_45``.
        kind: ``grasp`` (close on the object, carry it) or ``push`` (closed fingers press it).
        pose: (4, 4) TCP pose in the cuboid's frame.
        width: object width between the fingers [m] (0 for pushes).
        standoff: (hooks) how far outside the face [m], along its outward normal, the
            gripper comes down before moving onto ``pose``; 0 for the others.
    """

    name: str
    kind: str
    pose: np.ndarray
    width: float
    standoff: float = 0.0


def _frame(approach: np.ndarray, fingers: np.ndarray, position: np.ndarray) -> np.ndarray:
    """TCP pose with +z = approach, +y = fingers (made orthogonal), at ``position``."""
    z = approach / np.linalg.norm(approach)
    y = fingers - (fingers @ z) * z
    y /= np.linalg.norm(y)
    T = np.eye(4)
    T[:3, :3] = np.stack([np.cross(y, z), y, z], axis=1)
    T[:3, 3] = position
    return T


def rim_depth(height: float) -> float:
    """[m] how far below the rim of an open vessel ``height`` [m] tall a rim grasp's TCP goes: :data:`RIM_DEPTH`,
    less where the inner fingertip would come nearer the inside bottom than :data:`TABLE_CLEARANCE`."""
    return min(RIM_DEPTH, height - RIM_WALL - FINGERTIP_BELOW_TCP - TABLE_CLEARANCE)


def rim_fits(height: float) -> bool:
    """Whether an open vessel ``height`` [m] tall has a rim the gripper holds (:func:`rim_depth` at least
    :data:`MIN_RIM_DEPTH`)."""
    return rim_depth(height) >= MIN_RIM_DEPTH


def _axis_name(world_dir: np.ndarray) -> str:
    """'+x', '-y', ... for the world axis closest to ``world_dir``."""
    i = int(np.argmax(np.abs(world_dir[:2])))
    return ("+" if world_dir[i] > 0 else "-") + "xy"[i]


def candidate_poses(object_rot: np.ndarray, object_size: np.ndarray, *, push_height: float | None = None,
                    pushing: bool = False, hooking: bool = False, open_top: bool = False) -> list[GraspPose]:
    """All predefined poses on a cuboid of ``object_size`` at rotation ``object_rot`` (onset frame).

    Args:
        object_rot: (3, 3) cuboid rotation at the contact onset (local to world).
        object_size: (3,) edge lengths [m].
        push_height: height [m] of the demonstrated contact above the cuboid's centre
            (pushes only; clipped to the face).
        pushing: return push poses (True) or grasp poses (False).
        hooking: with grasp poses, also return hook poses (for pulls).
        open_top: with grasp poses, also return rim poses (an open vessel, open at its top at the onset).
    """
    size = np.asarray(object_size, float)
    up_world = object_rot.T @ np.array([0.0, 0.0, 1.0])  # world up in the cuboid's frame
    up_axis = int(np.argmax(np.abs(up_world)))
    up = np.zeros(3)
    up[up_axis] = math.copysign(1.0, up_world[up_axis])
    side_axes = [i for i in range(3) if i != up_axis]
    top = size[up_axis] / 2
    poses = []
    faces = []  # (outward normal in the cuboid's frame, tangent axis index, name)
    for i in side_axes:
        j = side_axes[0] if i == side_axes[1] else side_axes[1]
        for sign in (1.0, -1.0):
            n = np.zeros(3)
            n[i] = sign
            faces.append((n, j, _axis_name(object_rot @ n)))
    if pushing:
        lowest, highest = -top + MIN_PUSH_HEIGHT, top - PUSH_BELOW_TOP
        h = float(np.clip(0.0 if push_height is None else push_height, lowest, max(lowest, highest)))
        for n, j, face in faces:
            tangent = np.eye(3)[j]
            for tilt in (30, 45, 60):
                a = -math.cos(math.radians(tilt)) * n - math.sin(math.radians(tilt)) * up
                position = n * size[int(np.argmax(np.abs(n)))] / 2 + up * h
                poses.append(GraspPose(f"push_{face}_{tilt}", "push", _frame(a, tangent, position), 0.0))
        return poses
    if hooking:
        h = -top + HOOK_HEIGHT
        for n, j, face in faces:
            half_n = size[int(np.argmax(np.abs(n)))] / 2
            for tilt in (60, 75):
                slope = math.tan(math.radians(tilt))
                a = math.cos(math.radians(tilt)) * n - math.sin(math.radians(tilt)) * up
                position = n * (half_n + HOOK_OFFSET) + up * h
                standoff = max(0.0, (top - h) / slope + HOOK_CLEARANCE - HOOK_OFFSET)
                poses.append(GraspPose(f"hook_{face}_{tilt}", "push", _frame(a, np.eye(3)[j], position), 0.0,
                                       standoff))
    fits = lambda axis: size[axis] <= MAX_OPENING - FIT_MARGIN  # noqa: E731
    for top_depth, suffix in ((TOP_DEPTH, ""), (SHALLOW_DEPTH, "_shallow")):
        depth = min(top_depth, size[up_axis] - FINGERTIP_BELOW_TCP - TABLE_CLEARANCE)
        for j in side_axes:
            if fits(j):
                for sign in (1.0, -1.0):
                    fingers = sign * np.eye(3)[j]
                    name = f"top_{_axis_name(object_rot @ np.eye(3)[j])[1]}{'' if sign > 0 else '_flip'}{suffix}"
                    poses.append(GraspPose(name, "grasp", _frame(-up, fingers, up * (top - depth)),
                                           float(size[j])))
    for n, j, face in faces:
        if not fits(j):
            continue
        half_n = size[int(np.argmax(np.abs(n)))] / 2
        edge = n * half_n + up * top
        a = -(n + up) / math.sqrt(2.0)
        for sign in (1.0, -1.0):
            fingers = sign * np.eye(3)[j]
            flip = "" if sign > 0 else "_flip"
            poses.append(GraspPose(f"edge_{face}{flip}", "grasp", _frame(a, fingers, edge + EDGE_DEPTH * a),
                                   float(size[j])))
            side_depth = min(SIDE_DEPTH, half_n)
            poses.append(GraspPose(f"side_{face}{flip}", "grasp", _frame(-n, fingers, n * (half_n - side_depth)),
                                   float(size[j])))
    if open_top and rim_fits(2 * top):
        poses += _rim_poses(faces, size, up, top)
    return poses


def _rim_poses(faces: list, size: np.ndarray, up: np.ndarray, top: float) -> list[GraspPose]:
    """From above onto the rim of each face's wall (outward normals ``faces``, cuboid frame), the fingers
    closing across the wall: the TCP at the wall's mid-thickness, :func:`rim_depth` below the top ``top``."""
    poses = []
    depth = rim_depth(2 * top)
    for n, _, face in faces:
        position = n * (size[int(np.argmax(np.abs(n)))] / 2 - RIM_WALL / 2) + up * (top - depth)
        for sign in (1.0, -1.0):
            flip = "" if sign > 0 else "_flip"
            poses.append(GraspPose(f"rim_{face}{flip}", "grasp", _frame(-up, sign * n, position), RIM_WALL))
    return poses


def rank_poses(poses: list[GraspPose], object_rot: np.ndarray, hand_axis: np.ndarray, *,
               push_direction: np.ndarray | None = None) -> list[tuple[float, GraspPose]]:
    """Poses sorted by cost [deg]: the angle between their approach and the demonstrated one.

    The demonstrated approach is ``-hand_axis`` (the hand axis runs from the tip to the
    arm). With ``push_direction`` (push and pull: the object's horizontal displacement),
    only poses whose horizontal approach points along it (within 60 degrees) are kept: a
    push moves the object the way the pressing fingers face. A pressing pose (push, hook)
    then also counts :data:`SLANT_WEIGHT` times the angle between its horizontal approach
    and ``push_direction``: a face pressed at a slant turns the object away, and the fingers
    slide off it (the more so on a slippery table), so the face most square to the motion
    comes first unless it is much further from the demonstrated approach.
    """
    demo = -np.asarray(hand_axis, float) / np.linalg.norm(hand_axis)
    ranked = []
    for pose in poses:
        a = object_rot @ pose.pose[:3, 2]
        angle = math.degrees(math.acos(float(np.clip(a @ demo, -1.0, 1.0))))
        if push_direction is not None:
            a_h = a[:2] / max(np.linalg.norm(a[:2]), 1e-9)
            d_h = push_direction[:2] / max(np.linalg.norm(push_direction[:2]), 1e-9)
            if np.linalg.norm(a[:2]) < 0.2 or a_h @ d_h < 0.5:
                continue
            if pose.kind == "push":
                angle += SLANT_WEIGHT * math.degrees(math.acos(float(np.clip(a_h @ d_h, -1.0, 1.0))))
        ranked.append((angle, pose))
    ranked.sort(key=lambda item: item[0])
    return ranked
