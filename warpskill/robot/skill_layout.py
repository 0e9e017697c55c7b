"""A skill from a reconstruction, and carried to a new layout: the layout planning of the skill record.

:func:`skill_from` fills a :class:`~warpskill.contract.skill.Skill` (``skill.npz``, ``docs/formats.md``)
with the action, the timing (grasp signal, contact onset and release [s]), the cuboid sizes, the
demonstrated layout, and the motion relative to the objects:

- the object's motion relative to its start: the displacement in the world's axes (a pull
  or push keeps its world direction: left to right stays left to right; a pick-up lifts up)
  and the rotation in the world's frame; a carried object's (``pick_up``, ``put_*``) turns
  with the layout's yaw, so that it tilts as demonstrated relative to itself and comes to
  rest on the same face, as high;
- the hand relative to the object (approach: to the object at the onset; contact: to the
  object in that frame; retreat: to the object at the release). Grasp actions (``pick_up``,
  ``put_*``) hold the object somewhere on it: the hand is kept in the object's own axes,
  scaled with its size. Pulls and pushes press or hook the face that faces the world
  direction: the hand is kept in the world's axes at the object's centre, moved out or
  in with that face;
- for ``put_*``, the release (the last frame for a put held to the video's end) relative to
  the (first) static box: the object centre's offset from the box centre (``release_offset``,
  world axes) and the gap between them along the relation's side (``release_gap``). At a new layout the relation is kept as each action means it:

  - ``put_next_to``: in the box's own frame: the side is the box's horizontal axis nearest the
    demonstrated offset, the object released at the demonstrated gap out of that face and at
    the demonstrated offset along it (clamped to the face), wherever the box is turned;
  - ``put_behind`` / ``put_in_front_of``: as seen from the camera that judges them
    (:data:`VIEW`, :mod:`warpskill.contract.evaluation`): along / against the viewing
    direction at the demonstrated gap between the world extents, at the demonstrated
    sideways (world x) offset clamped to the box's width;
  - ``put_onto``: on the box's top face at the demonstrated offset in the box's frame,
    clamped to the face (:data:`ONTO_INSET`);
  - ``pick_up``: to the demonstrated height (the lift of the object's bottom kept).

  The gap is at least touching: a reconstruction that ends the object a little inside the
  box meant it beside the box.

An object held from the first frame was carried into view: in a layout it starts where the
demonstration has slowed down for good (:func:`takeover`), resting on the table.

A carried object (``pick_up``, ``put_*``) whose path in a new layout would run into a
static box is lifted over it, as a robot would carry it: a reconstruction's path may graze
a box's edge by a few centimetres.

The skill keeps what the object is (the reconstruction's ``object_noun``), and the layout's
reconstruction carries it: an open vessel too wide for the gripper is held by its rim at any
layout, as in the demonstration's replay, and substituted only where no face or rim fits
(:func:`~warpskill.robot.sizes.fit_sizes`).

A :class:`~warpskill.contract.skill.Layout` places the object's start and each static box on the table
(x, y, yaw) in the reconstruction's world frame; :func:`apply_skill` makes the reconstruction of the
skill there, which retargeting, replays and :func:`~warpskill.contract.evaluation.evaluate`
consume as any reconstruction. It refuses, before any planning, a layout where the relation
cannot be met: boxes that overlap, a path that runs into a static box, and a pick-up or put
whose laid-out scene fails the action's own checks (e.g. a next-to side that the box's turn
shows to the camera as behind it).
"""

from __future__ import annotations

import math

import numpy as np

from warpskill.contract.actions import check_action
from warpskill.contract.evaluation import evaluate
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.skill import Layout, LayoutError, Skill, SkillError
from warpskill.geometry import NEVER_HELD, heading, held_span, is_held, release_frame, rot_z, support_extent

__all__ = ["ONTO_INSET", "SWING_SPEED", "TAKEOVER_SPEED", "VIEW", "apply_skill", "demonstrated_layout", "overlap_depth",
           "skill_from", "takeover"]

OVERLAP_TOLERANCE = 0.01
"""[m] boxes that interpenetrate deeper than this make a layout impossible."""

CARRY_CLEARANCE = 0.01
"""[m] a carried object whose path would run into a static box passes this far above its top."""

GRAZE = 0.005
"""[m] a carried object touching a static box less deeply than this (set down on it) is not lifted."""

LIFT_RATE = 0.2
"""[m/s] how fast a carried object is raised to that clearance and lowered from it."""

MIN_TRAVEL = 0.01
"""[m] a pull or push moving the object less than this has no world direction to keep."""

ONTO_INSET = 0.03
"""[m] a put onto lets go with the object's centre at least this far inside the edges of the static
box's top (half the top's half extent on a top narrower than twice that): the object settles by a
centimetre or so, and a centre at the edge tips it off the box (a reconstruction may end the
object beside the box it was put onto)."""

VIEW = np.array([0.0, 1.0, 0.0])
"""The camera's horizontal viewing direction in the world (``docs/formats.md``: y away from the
camera): put behind / in front of are judged along it (:mod:`warpskill.contract.evaluation`)."""

SWING_SPEED = 1.7
"""[m/s] an object held from the first frame that moves faster than this (between two frames)
is still being swung into view: a new layout starts it where it has slowed down for good
(:func:`takeover`). The Panda's Cartesian speed limit; the robot takes over a carried-in
object no faster than this (:data:`warpskill.robot.retargeting.CARRY_SPEED`)."""

TAKEOVER_SPEED = 0.5 * SWING_SPEED
"""[m/s] the object of a swing is taken over at the first frame it moves slower than this: the
robot starts it from rest (at the swing speed itself, the plan lags 3 cm behind at once)."""


def _on_top_floor(pos: np.ndarray, rot: np.ndarray, size: np.ndarray, static_pos: np.ndarray,
                  static_rot: np.ndarray, static_size: np.ndarray) -> np.ndarray:
    """(F,) [m] the lowest centre height of an object (centres ``pos`` (F, 3), rotations ``rot``
    (F, 3, 3)) set down on a static box's top: its bottom at most :data:`GRAZE` into the box,
    in the frames where its centre is over the top face; -inf elsewhere.

    The physics' point contact lets an object resting on a static box sink into it, by up to
    about a centimetre over the seconds after the release; a skill set down on the box stands
    on its top instead, as a layout's overlap check asks.
    """
    up = np.array([0.0, 0.0, 1.0])
    local = (pos - static_pos) @ static_rot
    over = np.all(np.abs(local[:, :2]) <= 0.5 * static_size[:2], axis=1)
    top = static_pos[2] + support_extent(static_rot, static_size, up)
    floor = top - GRAZE + np.array([support_extent(r, size, up) for r in rot])
    return np.where(over, floor, -np.inf)


def overlap_depth(pos_a, rot_a, size_a, pos_b, rot_b, size_b) -> float:
    """How deep [m] two cuboids interpenetrate (0 where they are apart): the least overlap over
    the separating-axis candidates (the 3 + 3 face normals and their 9 cross products)."""
    axes = [rot_a[:, i] for i in range(3)] + [rot_b[:, i] for i in range(3)]
    axes += [np.cross(rot_a[:, i], rot_b[:, j]) for i in range(3) for j in range(3)]
    gap = np.asarray(pos_b, float) - np.asarray(pos_a, float)
    depth = math.inf
    for axis in axes:
        norm = np.linalg.norm(axis)
        if norm < 1e-9:
            continue
        axis = axis / norm
        reach = support_extent(rot_a, size_a, axis) + support_extent(rot_b, size_b, axis)
        depth = min(depth, reach - abs(float(gap @ axis)))
        if depth <= 0.0:
            return 0.0
    return depth


def demonstrated_layout(skill: Skill) -> Layout:
    """The demonstrated layout: :func:`apply_skill` of it reproduces the reconstruction (for an object
    carried into view, from its take-over on, resting on the table before: :func:`takeover`)."""
    start_pos, start_rot, _, _ = _motion(skill)
    return Layout(object=(*start_pos[:2], heading(start_rot)),
                  statics=tuple((*p[:2], heading(R)) for p, R in zip(skill.static_pos, skill.static_rot)))


def takeover(skill: Skill) -> int:
    """The frame a new layout starts the object at: 0, or for an object held from the first
    frame (carried into view: its start is unknown), the first frame after the last one, before
    the last held frame, at which it moves faster than :data:`SWING_SPEED` (0 where none does)
    from which it moves no faster than :data:`TAKEOVER_SPEED` to the next.

    Before it, the demonstration swings the object in from out of view, metres away on a
    real video's reconstruction; no layout on the table holds that path and no robot
    follows it. In a layout the object waits, held, at its take-over pose until then
    (:func:`apply_skill`), so the demonstrated layout reproduces the reconstruction from this
    frame on only.
    """
    if not _carried_in(skill):
        return 0
    speed = np.linalg.norm(np.diff(skill.object_motion_pos, axis=0), axis=1) * skill.fps  # (N - 1,)
    _, k_off = held_span(skill.grasped)
    last = skill.num_frames - 1 if k_off is None else k_off - 1
    fast = np.flatnonzero(speed[:last] > SWING_SPEED)
    if len(fast) == 0:
        return 0
    k = int(fast[-1]) + 1
    while k < last and speed[k] > TAKEOVER_SPEED:  # from rest, the robot takes it once it has slowed down
        k += 1
    return k


def _carried_in(skill: Skill) -> bool:
    """Whether the object is held from the first frame and moves at once (carried into view;
    a skill carried to a layout waits still at its start instead)."""
    return bool(is_held(skill.grasped[0]) and skill.num_frames > 1
                and np.any(skill.object_motion_pos[1] != skill.object_motion_pos[0]))


def _motion(skill: Skill) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The start pose (3,), (3, 3) and the motion relative to it (N, 3), (N, 3, 3) that a layout places.

    The demonstrated ones; for an object carried into view (held from the first frame), the
    object starts at its take-over pose (frame k of :func:`takeover`, often 0) turned onto a
    face: a carried one (pick-ups, puts) onto its largest (its reconstructed tilt in the air
    says nothing of how it rests, and would stand it on an edge or on end), a pushed or
    pulled one onto the face nearest down (it was seen on the table), and
    lowered onto the table (its bottom at z = 0), waits there until frame k, then follows the
    demonstrated path, the lowering shrinking linearly to none at the release (or the last frame)
    and never taking the object's bottom below the table where the demonstration keeps it above
    (a path that comes down to the table soon after the take-over would otherwise run under it).
    """
    k = takeover(skill)
    if not _carried_in(skill):
        return skill.object_start_pos, skill.object_start_rot, skill.object_motion_pos, skill.object_motion_rot
    start_rot = _on_a_face(skill.object_motion_rot[k] @ skill.object_start_rot, skill.object_size,
                           largest=not _world_directed(skill.action))
    start_pos = skill.object_start_pos + skill.object_motion_pos[k]
    drop = start_pos[2] - support_extent(start_rot, skill.object_size, np.array([0.0, 0.0, 1.0]))
    start_pos = start_pos - np.array([0.0, 0.0, drop])
    _, k_off = skill.frames()
    end = (skill.num_frames - 1) if k_off is None else k_off
    motion_rot = skill.object_motion_rot @ skill.object_motion_rot[k].T  # the object's turn since frame k
    motion_rot[:k] = np.eye(3)
    frames = np.arange(skill.num_frames)
    lowering = drop * (1.0 - np.clip((frames - k) / max(end - k, 1), 0.0, 1.0))
    lowering = np.minimum(lowering, _clearance(skill, motion_rot @ start_rot))
    motion_pos = skill.object_motion_pos - skill.object_motion_pos[k]
    motion_pos[:, 2] += drop - lowering
    motion_pos[:k] = 0.0
    return start_pos, start_rot, motion_pos, motion_rot


def _clearance(skill: Skill, rot: np.ndarray) -> np.ndarray:
    """(N,) how far [m] the demonstrated object path can come down, per frame, with the object
    turned to ``rot`` (N, 3, 3), before its bottom goes below the table or below the
    demonstrated bottom where that is under the table (never negative)."""
    up = np.array([0.0, 0.0, 1.0])
    z = skill.object_start_pos[2] + skill.object_motion_pos[:, 2]
    demo_rot = skill.object_motion_rot @ skill.object_start_rot
    demo_bottom = z - np.array([support_extent(r, skill.object_size, up) for r in demo_rot])
    bottom = z - np.array([support_extent(r, skill.object_size, up) for r in rot])
    return np.maximum(bottom - np.minimum(demo_bottom, 0.0), 0.0)


def apply_skill(skill: Skill, layout: Layout) -> Reconstruction:
    """The reconstruction of the skill performed in ``layout`` (see the module doc).

    Raises:
        LayoutError: a static box count other than the skill's, boxes that overlap at
            the start, an object path that runs into a static box, or a relation not met
            (:func:`_check_relation`); its ``reason`` says which in a few words.
    """
    if len(layout.statics) != skill.num_static:
        raise LayoutError(f"layout refused: it places {len(layout.statics)} static box(es), the "
                          f"{skill.action} skill has {skill.num_static}", reason="static box count")
    static_pos, static_rot = _statics(skill, layout)
    size = skill.object_size if layout.object_size is None else np.asarray(layout.object_size)
    object_pos, object_rot = _object_path(skill, layout, size, static_pos, static_rot)
    hand_pos, hand_rot = _hand_path(skill, object_pos, object_rot, size)
    recon = Reconstruction(
        fps=skill.fps, t=skill.t, hand_pos=hand_pos, hand_rot=hand_rot, grasp=skill.grasp, grasped=skill.grasped,
        object_pos=object_pos, object_rot=object_rot, object_size=size, static_pos=static_pos,
        static_rot=static_rot, static_size=skill.static_size, camera_K=skill.camera_K,
        camera_elevation=skill.camera_elevation, camera_height=skill.camera_height, image_size=skill.image_size,
        action=skill.action, loss=skill.loss, object_noun=np.array(skill.object_noun))
    _check_overlaps(recon)
    _check_relation(recon)
    return recon


def _statics(skill: Skill, layout: Layout) -> tuple[np.ndarray, np.ndarray]:
    """(K, 3) centres and (K, 3, 3) rotations of the static boxes in ``layout`` (heights kept)."""
    pos = skill.static_pos.copy()
    rot = skill.static_rot.copy()
    for k, (x, y, yaw) in enumerate(layout.statics):
        pos[k, :2] = x, y
        rot[k] = rot_z(yaw - heading(skill.static_rot[k])) @ skill.static_rot[k]
    return pos, rot


def _object_path(skill: Skill, layout: Layout, size: np.ndarray, static_pos: np.ndarray,
                 static_rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) centres and (N, 3, 3) rotations of the object in ``layout``.

    The demonstrated motion from the new start, resting as deep as before (a resized
    object keeps its bottom's heights); a ``put_*`` path bends, with the progress along
    it, to end at the release relative to the static box, and settles from there as it did
    relative to the box (next to, onto: kept over the top, :func:`_on_top_face`) or to the
    camera (behind, in front of); a carried object is lifted
    over the static boxes in its way (:func:`_carry_lift`); an object put onto the box
    rests on its top from the release on, at most :data:`GRAZE` deep in it
    (:func:`_on_top_floor`).
    """
    x, y, yaw = layout.object
    demo_pos, demo_rot, motion_pos, motion_rot = _motion(skill)
    turn = rot_z(yaw - heading(demo_rot))
    start_rot = turn @ demo_rot
    rot = motion_rot @ start_rot if _world_directed(skill.action) else turn @ motion_rot @ demo_rot
    start = np.array([x, y, demo_pos[2]])
    up = np.array([0.0, 0.0, 1.0])
    start[2] += support_extent(start_rot, size, up) - support_extent(demo_rot, skill.object_size, up)
    pos = start + motion_pos
    k_on, k_off = skill.frames()
    if skill.action.startswith("put_") and skill.num_static:
        k = release_frame(skill.grasped)  # a put held to the video's end meets its relation there
        target = _release_point(skill, pos[k], rot[k], size, static_pos[0], static_rot[0])
        pos += _progress(motion_pos, k_on, k)[:, None] * (target - pos[k])
        pos[k:] = pos[k] + (pos[k:] - pos[k]) @ _relation_turn(skill, static_rot[0]).T  # settling beside it
        if skill.action == "put_onto":  # it settles on the top, not off it
            pos[k:] = _on_top_face(skill, pos[k:], static_pos[0], static_rot[0])
            floor = _on_top_floor(pos[k:], rot[k:], size, static_pos[0], static_rot[0], skill.static_size[0])
            pos[k:, 2] = np.maximum(pos[k:, 2], floor)
    if not _world_directed(skill.action):
        pos[:, 2] += _carry_lift(pos, rot, size, (static_pos, static_rot, skill.static_size), k_on, k_off, skill.fps)
    return pos, rot


def _release_point(skill: Skill, where: np.ndarray, rot: np.ndarray, size: np.ndarray, static_pos: np.ndarray,
                   static_rot: np.ndarray) -> np.ndarray:
    """(3,) the release centre of the object (rotation ``rot``, edges ``size`` [m]) relative to the
    static box at ``static_pos``, ``static_rot`` as the module doc keeps each relation; its
    height ``where[2]`` kept."""
    local = skill.static_rot[0].T @ skill.release_offset  # in the demonstrated box's frame
    if skill.action == "put_onto":  # on the box: the centre inside its top, ONTO_INSET from the edges
        target = _on_top_face(skill, static_pos + static_rot @ local, static_pos, static_rot)
    else:  # beside the box: the demonstrated gap out of the side, the offset along it clamped to it
        _, along_demo = _sides(skill.action, local, skill.static_rot[0])
        out, along = _sides(skill.action, local, static_rot)
        width = support_extent(static_rot, skill.static_size[0], along)
        reach = support_extent(static_rot, skill.static_size[0], out) + support_extent(rot, size, out)
        lateral = float(np.clip(skill.release_offset @ along_demo, -width, width))
        target = static_pos + (reach + max(skill.release_gap, 0.0)) * out + lateral * along
    target[2] = where[2]
    return target


def _on_top_face(skill: Skill, pos: np.ndarray, static_pos: np.ndarray, static_rot: np.ndarray) -> np.ndarray:
    """(..., 3) object centres ``pos`` (..., 3) moved horizontally, in the static box's frame, to lie
    over its top at least :data:`ONTO_INSET` inside the edges."""
    half = 0.5 * skill.static_size[0, :2]
    limit = np.maximum(half - ONTO_INSET, 0.5 * half)
    local = (pos - static_pos) @ static_rot
    local[..., :2] = np.clip(local[..., :2], -limit, limit)
    return static_pos + local @ static_rot.T


def _relation_turn(skill: Skill, static_rot: np.ndarray) -> np.ndarray:
    """(3, 3) the turn about z from the demonstrated put's relation frame to the layout's: the
    static box's (rotation ``static_rot``) turn for next to and onto, none for behind and in
    front of (the camera's frame)."""
    if skill.action in ("put_behind", "put_in_front_of"):
        return np.eye(3)
    return rot_z(heading(static_rot) - heading(skill.static_rot[0]))


def _sides(action: str, local: np.ndarray, static_rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit horizontal world directions (3,) out of a static box (rotation ``static_rot``) to the
    side a put beside it releases on, and along that side, for the demonstrated release offset
    ``local`` (3,) [m] in the demonstrated box's frame: for ``put_next_to`` the box's own
    horizontal axis nearest ``local`` (towards it) and the other one; for ``put_behind`` /
    ``put_in_front_of`` the camera's :data:`VIEW` / its opposite and the world x axis."""
    if action == "put_next_to":
        i = int(np.argmax(np.abs(local[:2])))
        return math.copysign(1.0, local[i]) * _horizontal(static_rot[:, i]), _horizontal(static_rot[:, 1 - i])
    return (VIEW if action == "put_behind" else -VIEW), np.array([1.0, 0.0, 0.0])


def _horizontal(axis: np.ndarray) -> np.ndarray:
    """(3,) the unit horizontal part of ``axis`` (3,)."""
    flat = np.array([axis[0], axis[1], 0.0])
    return flat / np.linalg.norm(flat)


def _release_gap(action: str, offset: np.ndarray, static_rot: np.ndarray, static_size: np.ndarray,
                 rot: np.ndarray, size: np.ndarray) -> float:
    """[m] the gap between a static box (rotation, edges) and an object (rotation, edges) released at
    ``offset`` (3,) [m, world axes] from the box's centre, along the side of :func:`_sides`
    (negative: they overlap); 0 for ``put_onto``."""
    if action == "put_onto":
        return 0.0
    out, _ = _sides(action, static_rot.T @ offset, static_rot)
    return float(offset @ out) - (support_extent(static_rot, static_size, out) + support_extent(rot, size, out))


def _hand_path(skill: Skill, object_pos: np.ndarray, object_rot: np.ndarray,
               size: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) hand tips and (N, 3, 3) hand frames relative to the object of the new layout."""
    ref = _reference_frames(skill.grasped, *skill.frames())
    ref_pos, ref_rot = object_pos[ref], object_rot[ref]
    if not _world_directed(skill.action):
        local = skill.hand_in_object_pos * (size / skill.object_size)
        return ref_pos + np.einsum("nij,nj->ni", ref_rot, local), ref_rot @ skill.hand_in_object_rot
    offset = skill.hand_in_object_pos.copy()
    _, start_rot, motion_pos, motion_rot = _motion(skill)
    direction = _travel_direction(motion_pos, *skill.frames())
    if direction is not None:  # the hand stays on the face that faces the world direction
        demo_rot = motion_rot[ref] @ start_rot
        for k in range(skill.num_frames):
            side = math.copysign(1.0, float(offset[k] @ direction))
            moved = (support_extent(ref_rot[k], size, direction)
                     - support_extent(demo_rot[k], skill.object_size, direction))
            offset[k] += side * moved * direction
    return ref_pos + offset, skill.hand_in_object_rot.copy()


def _on_a_face(rot: np.ndarray, size: np.ndarray, largest: bool) -> np.ndarray:
    """(3, 3) the rotation ``rot`` turned so that a cuboid of edge lengths ``size`` rests on a
    face: with ``largest``, its largest (the shortest axis made vertical), else the one nearest
    down (the axis nearest the vertical made vertical); the side that axis pointed to kept up,
    the more horizontal of the other two keeping its horizontal direction."""
    i = int(np.argmin(size)) if largest else int(np.argmax(np.abs(rot[2])))
    others = [a for a in range(3) if a != i]
    j = max(others, key=lambda a: float(np.hypot(rot[0, a], rot[1, a])))
    out = np.empty((3, 3))
    out[:, i] = (0.0, 0.0, 1.0 if rot[2, i] >= 0.0 else -1.0)
    col = np.array([rot[0, j], rot[1, j], 0.0])
    out[:, j] = col / np.linalg.norm(col)
    k = 3 - i - j
    out[:, k] = np.cross(out[:, i], out[:, j]) if (i + 1) % 3 == j else np.cross(out[:, j], out[:, i])
    return out


def _world_directed(action: str) -> bool:
    """Whether the action keeps its world direction (pulls and pushes)."""
    return action.startswith(("pull_", "push_"))


def _reference_frames(grasped: np.ndarray, k_on: int, k_off: int | None) -> np.ndarray:
    """(N,) the object frame each hand sample is relative to: the onset before it, the release after it."""
    ref = np.arange(len(grasped))
    ref[:k_on] = k_on
    if k_off is not None:
        ref[k_off:] = k_off
    return ref


def _travel_direction(motion_pos: np.ndarray, k_on: int, k_off: int | None) -> np.ndarray | None:
    """(3,) the unit horizontal direction the object travels while held; None below :data:`MIN_TRAVEL`."""
    travel = motion_pos[k_off if k_off is not None else -1] - motion_pos[k_on]
    travel[2] = 0.0
    length = float(np.linalg.norm(travel))
    return travel / length if length >= MIN_TRAVEL else None


def _progress(motion_pos: np.ndarray, k_on: int, k_off: int) -> np.ndarray:
    """(N,) 0 until the onset, the fraction of the held path travelled, 1 from the release.

    By path length; by time where the object barely moves.
    """
    steps = np.linalg.norm(np.diff(motion_pos[k_on:k_off + 1], axis=0), axis=1)
    if steps.sum() < 1e-6:
        steps = np.ones_like(steps)
    progress = np.zeros(len(motion_pos))
    progress[k_on + 1:k_off + 1] = np.cumsum(steps) / steps.sum()
    progress[k_off:] = 1.0
    return progress


def _carry_lift(pos: np.ndarray, rot: np.ndarray, size: np.ndarray, statics: tuple[np.ndarray, ...], k_on: int,
                k_off: int | None, fps: float) -> np.ndarray:
    """(N,) [m] how far to raise the object (centres ``pos`` (N, 3), rotations ``rot`` (N, 3, 3))
    in its held frames so that it passes :data:`CARRY_CLEARANCE` above each static box
    (``statics``: (K, 3) centres, (K, 3, 3) rotations, (K, 3) sizes) it would run into deeper
    than :data:`GRAZE`; raised and lowered at :data:`LIFT_RATE`, 0 outside the held frames."""
    end = len(pos) if k_off is None else k_off
    up = np.array([0.0, 0.0, 1.0])
    need = np.zeros(len(pos))
    for f in range(k_on, end):
        for static in zip(*statics):
            if overlap_depth(pos[f], rot[f], size, *static) > GRAZE:
                top = static[0][2] + support_extent(static[1], static[2], up)
                need[f] = max(need[f], top + CARRY_CLEARANCE - (pos[f, 2] - support_extent(rot[f], size, up)))
    if not need.any():
        return need
    frames = np.arange(len(pos))
    lift = np.max(need[None, :] - LIFT_RATE / fps * np.abs(frames[:, None] - frames[None, :]), axis=1).clip(min=0.0)
    lift[:k_on] = lift[end:] = 0.0
    return lift


def _check_overlaps(recon: Reconstruction) -> None:
    """Refuse boxes that interpenetrate: static boxes with each other, the object with one along its path."""
    statics = list(zip(recon.static_pos, recon.static_rot, recon.static_size))
    for i in range(len(statics)):
        for j in range(i + 1, len(statics)):
            depth = overlap_depth(*statics[i], *statics[j])
            if depth > OVERLAP_TOLERANCE:
                raise LayoutError(f"layout refused: static boxes {i} and {j} overlap ({100 * depth:.1f} cm deep)",
                                  reason="footprints overlap")
    for k, static in enumerate(statics):
        for f in range(recon.num_frames):
            depth = overlap_depth(recon.object_pos[f], recon.object_rot[f], recon.object_size, *static)
            if depth > OVERLAP_TOLERANCE:
                where = "start" if f == 0 else f"path at t = {recon.t[f]:.2f} s"
                raise LayoutError(f"layout refused: the object's {where} overlaps static box {k} "
                                  f"({100 * depth:.1f} cm deep)",
                                  reason="footprints overlap" if f == 0 else "path runs into a static box")


def _check_relation(recon: Reconstruction) -> None:
    """Refuse a pick-up or put whose laid-out scene (the path the plan will follow, before any
    planning) fails the action's own checks (:func:`~warpskill.contract.evaluation.evaluate`):
    a next-to side turned to face the camera, a release not resting below the box's top."""
    action = str(recon.action)
    if _world_directed(action):
        return
    failed = [name for name, ok in evaluate(recon, action).checks.items() if not ok]
    if failed:
        where = "object ending at ({:.2f}, {:.2f}) m".format(*recon.object_pos[-1, :2])
        if recon.num_static:
            where += ", static box 0 at ({:.2f}, {:.2f}) m".format(*recon.static_pos[0, :2])
        raise LayoutError(f"layout refused: the {action.replace('_', ' ')} relation cannot be met: the laid-out "
                          f"scene fails {', '.join(failed)} ({where})", reason="relation not met")


def skill_from(recon: Reconstruction) -> Skill:
    """The skill a reconstruction teaches (see the module doc).

    Raises:
        SkillError: an unknown action, or a hand that never holds or touches the object.
    """
    if not str(recon.action):
        raise SkillError("action: the reconstruction's action is unknown; a skill needs one")
    action = check_action(str(recon.action))
    span = held_span(recon.grasped)
    if span is None:
        raise SkillError(f"grasped: {NEVER_HELD}")
    k_on, k_off = span
    ref = _reference_frames(recon.grasped, k_on, k_off)
    start_pos, start_rot = recon.object_pos[0], recon.object_rot[0]
    ref_pos, ref_rot = recon.object_pos[ref], recon.object_rot[ref]
    if _world_directed(action):
        hand_pos, hand_rot = recon.hand_pos - ref_pos, recon.hand_rot.copy()
    else:
        hand_pos = np.einsum("nji,nj->ni", ref_rot, recon.hand_pos - ref_pos)
        hand_rot = np.swapaxes(ref_rot, 1, 2) @ recon.hand_rot
    offset, gap = np.zeros(3), 0.0
    if action.startswith("put_") and recon.num_static:
        k = release_frame(recon.grasped)
        offset = recon.object_pos[k] - recon.static_pos[0]
        gap = _release_gap(action, offset, recon.static_rot[0], recon.static_size[0], recon.object_rot[k],
                           recon.object_size)
    fps = float(recon.fps)
    return Skill(
        action=action, fps=fps, t=recon.t.copy(), grasp=recon.grasp.copy(), grasped=recon.grasped.copy(),
        onset=k_on / fps, release=math.nan if k_off is None else k_off / fps, object_size=recon.object_size.copy(),
        object_start_pos=start_pos.copy(), object_start_rot=start_rot.copy(),
        object_motion_pos=recon.object_pos - start_pos, object_motion_rot=recon.object_rot @ start_rot.T,
        hand_in_object_pos=hand_pos, hand_in_object_rot=hand_rot, release_offset=offset, release_gap=gap,
        static_pos=recon.static_pos.copy(), static_rot=recon.static_rot.copy(), static_size=recon.static_size.copy(),
        camera_K=recon.camera_K.copy(), camera_elevation=float(recon.camera_elevation),
        camera_height=float(recon.camera_height), image_size=recon.image_size.copy(), loss=float(recon.loss),
        object_noun=str(recon.object_noun))
