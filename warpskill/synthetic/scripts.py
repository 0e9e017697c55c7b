"""Scripted scenes of the nine actions: the hand's waypoints and grasp signal, the cuboids, the rollout's inputs."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from warpskill.contract.actions import ACTIONS, check_action
from warpskill.engine.records import SceneInputs
from warpskill.engine.simulation import PhysicsConfig, substeps_per_frame
from warpskill.geometry import frame_from_axis, min_jerk, rot_z

GRASP_LEVEL = 0.02  # [m] |g| of the scripted grasp signal

PICK_UP_ENDINGS = ("held", "towards camera", "out of view")
"""How a ``"boxes"`` pick-up ends (by seed): held still in the air; brought towards the
camera; lifted out of the top of the view."""

TIP_DEPTH = 0.012  # [m] how deep the scripted tip enters the object

STATIC_CLEARANCE = 0.05  # [m] how far a carried object's bottom passes over a static's top (``Variant.clear_static``)


@dataclass
class Script:
    """A scripted scene: waypoints (time [s], tip position [m]) and everything static."""

    waypoints: list[tuple[float, np.ndarray]]
    hand_axis: np.ndarray
    grasp_on: float
    grasp_off: float | None
    object_pos: np.ndarray
    object_yaw: float
    object_size: np.ndarray
    static_pos: np.ndarray  # (K, 3)
    static_yaw: np.ndarray  # (K,)
    static_size: np.ndarray  # (K, 3)
    camera_height: float
    camera_elevation: float
    phase_end: float | None = None  # [s] where an annotator ends the action phase (None: at the release)


@dataclass(frozen=True)
class Variant:
    """The real videos' situations a ``"boxes"`` demonstration adds to the scripted scene."""

    ending: str = "held"  # pick_up: one of PICK_UP_ENDINGS
    far_start: bool = False  # the hand enters (and leaves) through the image border
    wide_static: float = 0.0  # > 0: the static box is this wide [m] (larger than / cut by the frame)
    object_size: tuple[float, float, float] | None = None  # [m] the object's edges instead of drawn ones
    narrow_static: bool = False  # the static box narrower than the object and deeper than wide
    static_yaw: float = 0.2  # [rad] the static box's yaw is drawn in [-static_yaw, static_yaw]
    object_yaw: float = 0.3  # [rad] the object's yaw is drawn in [-object_yaw, object_yaw] (not pushed or pulled)
    static_size: tuple[float, float, float] | None = None  # [m] a put action's static edges (x, y, z) instead of drawn ones
    clear_static: bool = False  # carry the object over the static's top, and stand the static a gap beside it
    static_away: float = 0.0  # [m] with clear_static, the static stands this much farther from the object (out of view)
    tip_depth: float = TIP_DEPTH  # [m] how deep the tip enters the object from its top (flat objects: less)
    side_reach: bool = False  # the hand reaches a top grasp from the side, not from the camera's side


NARROW_STATIC = ((0.4, 0.8), (0.12, 0.2))
"""Ranges of a narrow static box's width [share of the object's width] and depth [m]: an
object on it covers its top edge, as on the real videos' static objects, about as wide as
the object (a real static box's width is 0.83 of the object's, median)."""


TURNED_STATIC_YAW = 0.52
"""[rad] half-range of a turned static box's yaw (30 deg, as the independent generator
``synthdemo.py`` draws it; objects on a real table stand at any yaw)."""


TALL_THIN = ((0.02, 0.045), (0.02, 0.045), (0.15, 0.24))
"""[m] ranges of the width, depth and height of a tall thin object (a bottle, a pen standing up)."""


FLAT_LONG = ((0.12, 0.20), (0.02, 0.04), (0.01, 0.025))
"""[m] ranges of the width, depth and height of a long thin object lying flat (a pen, a
fork, a toothbrush on the table)."""

ASKEW_OBJECT_YAW = 1.2
"""[rad] half-range of an askew flat object's yaw (69 deg: cutlery and pens lie at any angle
to the camera; pushed and pulled objects keep yaw 0, their hand paths run along x)."""


def flat_long_size(rng: np.random.Generator) -> tuple[float, float, float]:
    """Edges [m] of a long thin object lying flat, drawn from :data:`FLAT_LONG`."""
    return tuple(float(rng.uniform(lo, hi)) for lo, hi in FLAT_LONG)


def tall_thin_size(rng: np.random.Generator) -> tuple[float, float, float]:
    """Edges [m] of a tall thin object, drawn from :data:`TALL_THIN`."""
    return tuple(float(rng.uniform(lo, hi)) for lo, hi in TALL_THIN)


def draw_variant(action: str, seed: int, rng: np.random.Generator) -> Variant:
    """The situations of one ``"boxes"`` demonstration: the pick-up ending by seed, the rest drawn."""
    far_start = bool(rng.random() < 0.5)
    wide = float(rng.uniform(0.3, 0.5)) if action.startswith("put_") and rng.random() < 0.35 else 0.0
    return Variant(ending=PICK_UP_ENDINGS[seed % len(PICK_UP_ENDINGS)], far_start=far_start, wide_static=wide)


def make_script(action: str, rng: np.random.Generator, duration: float, variant: Variant | None = None) -> Script:
    """Scene and hand waypoints for one action (world frame of docs/formats.md); ``variant`` adds
    the situations of a ``"boxes"`` demonstration (None: the plain scene)."""
    u = rng.uniform
    size = np.array([u(0.05, 0.11), u(0.05, 0.11), u(0.05, 0.12)])
    if variant is not None and variant.object_size is not None:
        size = np.array(variant.object_size)
    half_range = variant.object_yaw if variant is not None else Variant.object_yaw
    yaw = u(-half_range, half_range)
    centre = np.array([u(-0.08, 0.08), u(0.55, 0.7), size[2] / 2])
    static_pos, static_size, static_yaw = _static_box(action, centre, size, variant, rng)
    t_on, t_end = 0.3 * duration, duration
    t_off = None if action == "pick_up" else 0.72 * duration
    if action.startswith(("pull_", "push_")):
        yaw = 0.0
    axis, grasp, path = _hand_path(action, centre, size, static_pos, static_size, variant, rng)
    reach = 0.3 if variant is not None and variant.far_start else 0.15
    start = grasp + reach * axis + np.array([0.0, 0.0, 0.05])
    waypoints = [(0.0, start), (t_on - 0.05 * duration, grasp), (t_on + 0.04 * duration, grasp)]
    action_end = (t_off if t_off is not None else t_end) - 0.03 * duration
    phase_end = None
    if variant is not None and action == "pick_up":
        # The lift ends early; the annotator's action phase ends with it (or once the object
        # has left the view) while the hand still holds the object up to the video's end.
        action_end = 0.62 * duration if variant.ending == "held" else 0.85 * duration
        lifted_at = t_on + 0.04 * duration + (action_end - t_on - 0.04 * duration) / len(path)
        phase_end = (lifted_at + u(0.0, 0.08) * duration) if variant.ending != "out of view" else t_end
    times = np.linspace(t_on + 0.04 * duration, action_end, len(path) + 1)[1:]
    waypoints += list(zip(times, path))
    if t_off is not None:
        leave = path[-1] + reach * axis + np.array([0.0, 0.0, 0.05])
        waypoints += [(t_off + 0.04 * duration, path[-1]), (t_end - 0.05 * duration, leave)]
    return Script(
        waypoints=waypoints,
        hand_axis=axis,
        grasp_on=t_on,
        grasp_off=t_off,
        object_pos=centre,
        object_yaw=yaw,
        object_size=size,
        static_pos=static_pos,
        static_yaw=static_yaw,
        static_size=static_size,
        camera_height=u(0.38, 0.52),
        camera_elevation=u(0.5, 0.75),
        phase_end=phase_end,
    )


def _static_box(action: str, centre: np.ndarray, size: np.ndarray, variant: Variant | None,
                rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K, 3) centres, (K, 3) sizes and (K,) yaws of a put action's static box (K = 1; else K = 0);
    moves the object's ``centre`` (3,) beside it, in place."""
    u = rng.uniform
    if not action.startswith("put_"):
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    s_size = np.array([u(0.10, 0.18), u(0.10, 0.16), u(0.04, 0.12) if action == "put_onto" else u(0.08, 0.15)])
    side = rng.choice([-1.0, 1.0])
    static_pos = np.array([[centre[0] - side * 0.1, centre[1] + u(0.0, 0.05), s_size[2] / 2]])
    static_size = s_size[None]
    half_range = variant.static_yaw if variant is not None else Variant.static_yaw
    static_yaw = np.array([u(-half_range, half_range)])
    centre[0] += side * 0.12
    centre[1] -= 0.05
    if variant is not None and variant.narrow_static:
        (low, high), depth = NARROW_STATIC
        static_size = np.array([[u(low, high) * size[0], u(*depth), s_size[2]]])
    if variant is not None and variant.static_size is not None:
        static_size = np.array([variant.static_size])
    if variant is not None and variant.clear_static:
        # A static of any width, its near side a gap away from the object's (x, y).
        gap = u(0.03, 0.08)
        static_pos = np.array([[centre[0] - side * (gap + variant.static_away + (static_size[0, 0] + size[0]) / 2),
                                centre[1] + u(0.0, 0.05), static_size[0, 2] / 2]])
    if variant is not None and variant.wide_static:
        # A wide static box, cut by the frame: it extends away from the object.
        grow = variant.wide_static - s_size[0]
        static_size = static_size.copy()
        static_size[0, 0] = variant.wide_static
        static_pos = static_pos.copy()
        static_pos[0, 0] -= side * 0.5 * grow
    return static_pos, static_size, static_yaw


def _hand_path(action: str, centre: np.ndarray, size: np.ndarray, static_pos: np.ndarray, static_size: np.ndarray,
               variant: Variant | None, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """The hand's unit axis (3,), its grasp point (3,) and the held path's waypoints [(3,)]: the
    side facing the motion's start for push/pull, the top otherwise."""
    u = rng.uniform
    direction = 1.0 if action.endswith("left_to_right") else -1.0
    if action.startswith("pull_") or action.startswith("push_"):
        pushing = action.startswith("push_")
        # Pulling drags the object from the side it moves towards; pushing presses from behind.
        face = -direction if pushing else direction
        axis = np.array([face * 1.0, u(-0.5, -0.2), u(0.5, 0.9)])
        grasp = centre + np.array([face * (size[0] / 2 - TIP_DEPTH), 0.0, u(-0.2, 0.2) * size[2]])
        path = [grasp + np.array([direction * u(0.15, 0.25), 0.0, 0.0])]
    else:
        axis = np.array([u(-0.4, 0.4), u(-0.7, -0.3), 1.0])
        if variant is not None and variant.side_reach:  # a small object stays in sight beside the hand
            axis = np.array([rng.choice([-1.0, 1.0]) * u(0.6, 1.0), u(-0.2, 0.2), 1.0])
        tip = variant.tip_depth if variant is not None else TIP_DEPTH
        grasp = centre + np.array([0.0, 0.0, size[2] / 2 - tip])
        lift = grasp + np.array([0.0, 0.0, u(0.12, 0.18)])
        if variant is not None and variant.clear_static and len(static_pos):
            lift[2] = max(lift[2], static_size[0, 2] + STATIC_CLEARANCE + size[2] - tip)  # its bottom over the top
        if action == "pick_up":
            path = [lift]
            ending = variant.ending if variant is not None else None
            if ending == "towards camera":  # held up and brought towards the camera: its box grows
                path = [lift, lift + np.array([0.0, -u(0.35, 0.45), u(0.0, 0.06)])]
            elif ending == "out of view":  # lifted out of the top of the view
                path = [lift + np.array([0.0, 0.0, 0.25]), lift + np.array([0.0, u(0.0, 0.1), u(0.45, 0.6)])]
        else:
            target = _put_target(action, static_pos[0], static_size[0], size, rng)
            above = target + np.array([0.0, 0.0, 0.08])
            lowered = target + np.array([0.0, 0.0, size[2] / 2 - tip + 0.004])
            path = [lift, np.array([above[0], above[1], lift[2]]), lowered]
    return axis / np.linalg.norm(axis), grasp, path


def _put_target(action: str, s_pos: np.ndarray, s_size: np.ndarray, size: np.ndarray, rng) -> np.ndarray:
    """Where a put action leaves the object's centre, relative to the static box."""
    gap = rng.uniform(0.02, 0.05)
    if action == "put_onto":
        return np.array([s_pos[0], s_pos[1], s_size[2] + size[2] / 2])
    if action == "put_behind":
        offset = np.array([0.0, s_size[1] / 2 + gap + size[1] / 2, 0.0])
    elif action == "put_in_front_of":
        offset = np.array([0.0, -(s_size[1] / 2 + gap + size[1] / 2), 0.0])
    else:  # put_next_to
        offset = np.array([rng.choice([-1.0, 1.0]) * (s_size[0] / 2 + gap + size[0] / 2), 0.0, 0.0])
    return np.array([s_pos[0], s_pos[1], size[2] / 2]) + offset


def waypoint_path(waypoints: list[tuple[float, np.ndarray]], times: np.ndarray) -> np.ndarray:
    """Tip positions (T, 3) at ``times`` along minimum-jerk moves between waypoints."""
    out = np.empty((len(times), 3))
    for i, t in enumerate(times):
        k = np.searchsorted([w[0] for w in waypoints], t, side="right") - 1
        if k >= len(waypoints) - 1:
            out[i] = waypoints[-1][1]
            continue
        (t0, x0), (t1, x1) = waypoints[k], waypoints[k + 1]
        out[i] = x0 + (x1 - x0) * min_jerk((t - t0) / (t1 - t0))
    return out


def grasp_signal(script: Script, times: np.ndarray, ramp: float = 0.1) -> np.ndarray:
    """Scripted grasp signal [m] at ``times``: -GRASP_LEVEL, ramping up at the grasp and down at the release."""
    up = np.clip((times - script.grasp_on) / ramp, 0.0, 1.0)
    down = np.clip((times - script.grasp_off) / ramp, 0.0, 1.0) if script.grasp_off is not None else 0.0
    return GRASP_LEVEL * (2.0 * (up - down) - 1.0)


def scripted_inputs(
    script: Script, fps: float, duration: float, dtype=torch.float64
) -> tuple[SceneInputs, dict[str, object]]:
    """The rollout inputs (B = 1) of a script at ``fps`` [1/s] over ``duration`` [s], and the
    keyword options (``steps_per_frame``, ``fps``, ``config``) of
    :func:`warpskill.engine.simulation.simulate` for them: ``simulate(inputs, **options)``."""
    physics = PhysicsConfig()
    spf = substeps_per_frame(fps, physics)
    num_frames = int(round(duration * fps)) + 1
    dt = 1.0 / (fps * spf)
    edges = np.arange((num_frames - 1) * spf + 1) * dt
    tip = waypoint_path(script.waypoints, edges)
    grasp = grasp_signal(script, edges)
    velocity = np.concatenate([np.diff(tip, axis=0), np.zeros((len(edges) - 1, 3)), np.diff(grasp)[:, None]], 1) / dt
    K = len(script.static_pos)
    t = lambda a: torch.as_tensor(np.asarray(a), dtype=dtype)[None]  # noqa: E731
    inputs = SceneInputs(
        hand_pos0=t(tip[0]),
        hand_rot0=t(frame_from_axis(script.hand_axis)),
        grasp0=t(grasp[:1])[0],
        hand_vel=t(velocity),
        object_pos0=t(script.object_pos),
        object_rot0=t(rot_z(script.object_yaw)),
        object_size=t(script.object_size),
        static_pos=t(script.static_pos.reshape(K, 3)),
        static_rot=t(static_rotations(script)),
        static_size=t(script.static_size.reshape(K, 3)),
    )
    return inputs, dict(steps_per_frame=spf, fps=fps, config=physics)


def scripted_scene(action: str, seed: int = 0, duration: float = 4.0) -> Script:
    """The scripted scene of ``action`` that :func:`make_demonstration` starts from (before view checks)."""
    check_action(action)
    return make_script(action, np.random.default_rng([seed, ACTIONS.index(action)]), duration)


def static_rotations(script: Script) -> np.ndarray:
    """(K, 3, 3) rotations of the scripted static cuboids (K may be 0)."""
    return np.array([rot_z(a) for a in script.static_yaw]).reshape(len(script.static_yaw), 3, 3)
