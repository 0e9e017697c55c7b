"""Synthetic demonstrations with ground truth, for the tests, the benchmark and the demo.

A scripted hand (minimum-jerk moves between waypoints, a grasp signal that rises at the
contact onset and falls at the release) drives warpskill's own physics engine, so the
true trajectories obey the same approximate physics the optimiser assumes. The scene is
ray cast into exact masks, then spoiled with the errors real masks have: jittered
boundaries, spurious blobs, missing frames and a contact signal that is off by a frame or
flips in isolated frames.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from types import SimpleNamespace

import cv2
import numpy as np
import torch

from warpskill.contract.actions import ACTIONS, check_action
from warpskill.contract.camera import Intrinsics
from warpskill.contract.demonstration import Demonstration
from warpskill.contract.geometry import frame_from_axis, min_jerk
from warpskill.data.box_annotations import box_masks
from warpskill.engine.primitives import scene_cuboids
from warpskill.engine.raycast import raycast_masks
from warpskill.engine.records import SceneInputs
from warpskill.engine.simulation import PhysicsConfig, simulate, substeps_per_frame

GRASP_LEVEL = 0.02  # [m] |g| of the scripted grasp signal
INPUTS = ("masks", "boxes")
"""What a synthetic demonstration's masks are: the true silhouettes spoiled (``"masks"``), or
the ellipses inscribed in per-frame boxes of them, as the Something-Else reader makes them
(``"boxes"``; contact from annotator-like phases, scenes with the real videos' situations)."""
PICK_UP_ENDINGS = ("held", "towards camera", "out of view")
"""How a ``"boxes"`` pick-up ends (by seed): held still in the air; brought towards the
camera; lifted out of the top of the view."""
TIP_DEPTH = 0.012  # [m] how deep the scripted tip enters the object


@dataclass(frozen=True)
class Noise:
    """Mask and contact errors of a synthetic demonstration.

    Attributes:
        jitter: largest boundary erosion/dilation radius [px], drawn per frame and mask.
        blob_rate: probability that a frame's mask gains a spurious blob.
        missing_rate: probability that a frame's object mask is lost.
        contact_shift: largest shift [frames] of the contact onset and release.
        contact_flips: number of isolated frames whose contact flag is flipped.
    """

    jitter: int = 0
    blob_rate: float = 0.0
    missing_rate: float = 0.0
    contact_shift: int = 0
    contact_flips: int = 0


NOISE_LEVELS = {
    "none": Noise(),
    "low": Noise(jitter=1, blob_rate=0.03, missing_rate=0.02, contact_shift=1),
    "moderate": Noise(jitter=2, blob_rate=0.08, missing_rate=0.05, contact_shift=1, contact_flips=1),
    "high": Noise(jitter=3, blob_rate=0.15, missing_rate=0.10, contact_shift=2, contact_flips=2),
}


@dataclass
class _Script:
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
class _Variant:
    """The real videos' situations a ``"boxes"`` demonstration adds to the scripted scene."""

    ending: str = "held"  # pick_up: one of PICK_UP_ENDINGS
    far_start: bool = False  # the hand enters (and leaves) through the image border
    wide_static: float = 0.0  # > 0: the static box is this wide [m] (larger than / cut by the frame)


def make_demonstration(
    action: str,
    *,
    seed: int = 0,
    noise: str | Noise = "moderate",
    image_size: tuple[int, int] = (240, 427),
    fps: float = 12.0,
    duration: float = 4.0,
    input: str = "masks",
) -> Demonstration:
    """A synthetic demonstration of ``action`` with its ground truth in ``demo.truth``.

    Args:
        action: one of :data:`warpskill.contract.actions.ACTIONS`.
        seed: scene randomness (sizes, placements, camera, noise).
        noise: a name in :data:`NOISE_LEVELS` or a :class:`Noise`.
        image_size: (H, W) of the masks [px].
        fps: frame rate [1/s].
        duration: video length [s].
        input: one of :data:`INPUTS`. ``"boxes"``: each channel's mask is the ellipse
            inscribed in the box of its true visible silhouette (box edges jittered by up to
            ``noise.jitter`` px), rasterised by :func:`warpskill.data.box_annotations.box_masks`
            as for Something-Else; the contact is an annotator's action phase (from the
            grasp onset to the release; a pick-up's ends once the lift is done or the
            object leaves the view, while the hand still holds it); and the scenes add
            the real videos' situations (:data:`PICK_UP_ENDINGS`, a hand that enters
            through the border, wide static boxes cut by the frame).
    """
    check_action(action)
    if input not in INPUTS:
        raise ValueError(f"input: expected one of {INPUTS}, got {input!r}")
    noise = NOISE_LEVELS[noise] if isinstance(noise, str) else noise
    rng = np.random.default_rng([seed, ACTIONS.index(action)])
    boxes = input == "boxes"
    variant_rng = np.random.default_rng([seed, ACTIONS.index(action), 1])
    intrinsics = Intrinsics.default(*image_size)
    for _ in range(50):
        variant = _draw_variant(action, seed, variant_rng) if boxes else None
        script = _script(action, rng, duration, variant)
        truth = _simulate(script, fps, duration)
        masks = _render(truth, intrinsics)
        if _in_view(masks, partly=boxes):
            break
    else:  # pragma: no cover - the scripts are built to stay in view
        raise RuntimeError(f"could not place a {action} scene in view")
    truth["action"] = np.array(action)
    truth["camera_K"] = intrinsics.K
    truth["image_size"] = np.array(image_size)
    if boxes:
        contact = _noisy_contact(_phase_contact(script, truth, masks), replace(noise, contact_flips=0), rng)
        hand, obj, static = _box_channels(masks, noise, rng)
    else:
        contact = _noisy_contact(truth["grasped"] > 0.5, noise, rng)
        hand, obj, static = _noisy_channels(masks, noise, rng)
    return Demonstration.from_arrays(
        hand, obj, contact, fps, static_mask=static, camera_K=intrinsics.K, action=action, truth=truth
    )


def _noisy_channels(masks: np.ndarray, noise: Noise, rng: np.random.Generator):
    """Apply mask noise per channel: (hand (N,H,W), object (N,H,W), statics (K,N,H,W))."""
    hand = _noisy_masks(masks[:, 0], noise, rng, drop=False)
    obj = _noisy_masks(masks[:, 1], noise, rng, drop=True)
    statics = [_noisy_masks(masks[:, j], noise, rng, drop=False) for j in range(2, masks.shape[1])]
    return hand, obj, (np.stack(statics) if statics else None)


def _draw_variant(action: str, seed: int, rng: np.random.Generator) -> _Variant:
    """The situations of one ``"boxes"`` demonstration: the pick-up ending by seed, the rest drawn."""
    far_start = bool(rng.random() < 0.5)
    wide = float(rng.uniform(0.3, 0.5)) if action.startswith("put_") and rng.random() < 0.35 else 0.0
    return _Variant(ending=PICK_UP_ENDINGS[seed % len(PICK_UP_ENDINGS)], far_start=far_start, wide_static=wide)


def _box_channels(masks: np.ndarray, noise: Noise, rng: np.random.Generator):
    """Ellipses inscribed in jittered boxes of each channel's visible silhouette, as box annotations give them."""
    N, C, H, W = masks.shape
    channels = []
    for c in range(C):
        boxes = np.full((N, 4), np.nan)
        for k in range(N):
            rows, cols = np.nonzero(masks[k, c])
            if len(rows) == 0:
                continue
            box = np.array([cols.min(), rows.min(), cols.max() + 1.0, rows.max() + 1.0])
            if noise.jitter:
                box = box + rng.integers(-noise.jitter, noise.jitter + 1, size=4)
            x1, y1, x2, y2 = np.clip(box, 0, [W, H, W, H])
            if x2 - x1 >= 1 and y2 - y1 >= 1:
                boxes[k] = x1, y1, x2, y2
        channels.append(box_masks(boxes, (H, W)))
    statics = channels[2:]
    return channels[0], channels[1], (np.stack(statics) if statics else None)


def _phase_contact(script: _Script, truth: dict[str, np.ndarray], masks: np.ndarray) -> np.ndarray:
    """An annotator's action phase: from the grasp onset to the release, or to ``script.phase_end``
    (clipped to the object's last visible frame), as a per-frame contact signal."""
    grasped = truth["grasped"] > 0.5
    contact = grasped.copy()
    on = np.flatnonzero(grasped)
    if script.phase_end is not None and len(on):
        seen = np.flatnonzero(masks[:, 1].reshape(len(masks), -1).any(1))
        last = min(int(round(script.phase_end * float(truth["fps"]))), int(seen[-1]) if len(seen) else len(contact))
        contact[:] = False
        contact[on[0] : max(last, on[0]) + 1] = True
    return contact


def _script(action: str, rng: np.random.Generator, duration: float, variant: _Variant | None = None) -> _Script:
    """Scene and hand waypoints for one action (world frame of FORMATS.md); ``variant`` adds
    the situations of a ``"boxes"`` demonstration (None: the plain scene)."""
    u = rng.uniform
    size = np.array([u(0.05, 0.11), u(0.05, 0.11), u(0.05, 0.12)])
    yaw = u(-0.3, 0.3)
    centre = np.array([u(-0.08, 0.08), u(0.55, 0.7), size[2] / 2])
    static_pos = np.zeros((0, 3))
    static_size = np.zeros((0, 3))
    static_yaw = np.zeros(0)
    if action.startswith("put_"):
        s_size = np.array([u(0.10, 0.18), u(0.10, 0.16), u(0.04, 0.12) if action == "put_onto" else u(0.08, 0.15)])
        side = rng.choice([-1.0, 1.0])
        static_pos = np.array([[centre[0] - side * 0.1, centre[1] + u(0.0, 0.05), s_size[2] / 2]])
        static_size = s_size[None]
        static_yaw = np.array([u(-0.2, 0.2)])
        centre[0] += side * 0.12
        centre[1] -= 0.05
        if variant is not None and variant.wide_static:
            # A wide static box, cut by the frame: it extends away from the object.
            grow = variant.wide_static - s_size[0]
            static_size = static_size.copy()
            static_size[0, 0] = variant.wide_static
            static_pos = static_pos.copy()
            static_pos[0, 0] -= side * 0.5 * grow

    # Grasp points: the side facing the motion's start for push/pull, the top otherwise.
    t_on, t_off, t_end = 0.3 * duration, 0.72 * duration, duration
    direction = 1.0 if action.endswith("left_to_right") else -1.0
    if action.startswith("pull_") or action.startswith("push_"):
        pushing = action.startswith("push_")
        # Pulling drags the object from the side it moves towards; pushing presses from behind.
        face = -direction if pushing else direction
        axis = np.array([face * 1.0, u(-0.5, -0.2), u(0.5, 0.9)])
        grasp = centre + np.array([face * (size[0] / 2 - TIP_DEPTH), 0.0, u(-0.2, 0.2) * size[2]])
        path = [grasp + np.array([direction * u(0.15, 0.25), 0.0, 0.0])]
        yaw = 0.0
    else:
        axis = np.array([u(-0.4, 0.4), u(-0.7, -0.3), 1.0])
        grasp = centre + np.array([0.0, 0.0, size[2] / 2 - TIP_DEPTH])
        lift = grasp + np.array([0.0, 0.0, u(0.12, 0.18)])
        if action == "pick_up":
            path = [lift]
            t_off = None
            ending = variant.ending if variant is not None else None
            if ending == "towards camera":  # held up and brought towards the camera: its box grows
                path = [lift, lift + np.array([0.0, -u(0.35, 0.45), u(0.0, 0.06)])]
            elif ending == "out of view":  # lifted out of the top of the view
                path = [lift + np.array([0.0, 0.0, 0.25]), lift + np.array([0.0, u(0.0, 0.1), u(0.45, 0.6)])]
        else:
            target = _put_target(action, static_pos[0], static_size[0], size, rng)
            above = target + np.array([0.0, 0.0, 0.08])
            lowered = target + np.array([0.0, 0.0, size[2] / 2 - TIP_DEPTH + 0.004])
            path = [lift, np.array([above[0], above[1], lift[2]]), lowered]
    axis = axis / np.linalg.norm(axis)
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
    return _Script(
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


def _waypoint_path(waypoints: list[tuple[float, np.ndarray]], times: np.ndarray) -> np.ndarray:
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


def _grasp_signal(script: _Script, times: np.ndarray, ramp: float = 0.1) -> np.ndarray:
    """Scripted grasp signal [m] at ``times``: -GRASP_LEVEL, ramping up at the grasp and down at the release."""
    up = np.clip((times - script.grasp_on) / ramp, 0.0, 1.0)
    down = np.clip((times - script.grasp_off) / ramp, 0.0, 1.0) if script.grasp_off is not None else 0.0
    return GRASP_LEVEL * (2.0 * (up - down) - 1.0)


def _yaw(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def scripted_inputs(
    script: _Script, fps: float, duration: float, dtype=torch.float64
) -> tuple[SceneInputs, dict[str, object]]:
    """The rollout inputs (B = 1) of a script at ``fps`` [1/s] over ``duration`` [s], and the
    keyword options (``steps_per_frame``, ``fps``, ``config``) of
    :func:`warpskill.engine.simulation.simulate` for them: ``simulate(inputs, **options)``."""
    physics = PhysicsConfig()
    spf = substeps_per_frame(fps, physics)
    num_frames = int(round(duration * fps)) + 1
    dt = 1.0 / (fps * spf)
    edges = np.arange((num_frames - 1) * spf + 1) * dt
    tip = _waypoint_path(script.waypoints, edges)
    grasp = _grasp_signal(script, edges)
    velocity = np.concatenate([np.diff(tip, axis=0), np.zeros((len(edges) - 1, 3)), np.diff(grasp)[:, None]], 1) / dt
    K = len(script.static_pos)
    t = lambda a: torch.as_tensor(np.asarray(a), dtype=dtype)[None]  # noqa: E731
    inputs = SceneInputs(
        hand_pos0=t(tip[0]),
        hand_rot0=t(frame_from_axis(script.hand_axis)),
        grasp0=t(grasp[:1])[0],
        hand_vel=t(velocity),
        object_pos0=t(script.object_pos),
        object_rot0=t(_yaw(script.object_yaw)),
        object_size=t(script.object_size),
        static_pos=t(script.static_pos.reshape(K, 3)),
        static_rot=t(_static_rotations(script)),
        static_size=t(script.static_size.reshape(K, 3)),
    )
    return inputs, dict(steps_per_frame=spf, fps=fps, config=physics)


def scripted_scene(action: str, seed: int = 0, duration: float = 4.0) -> _Script:
    """The scripted scene of ``action`` that :func:`make_demonstration` starts from (before view checks)."""
    check_action(action)
    return _script(action, np.random.default_rng([seed, ACTIONS.index(action)]), duration)


def _static_rotations(script: _Script) -> np.ndarray:
    """(K, 3, 3) rotations of the scripted static cuboids (K may be 0)."""
    return np.array([_yaw(a) for a in script.static_yaw]).reshape(len(script.static_yaw), 3, 3)


def _simulate(script: _Script, fps: float, duration: float) -> dict[str, np.ndarray]:
    """Run the engine on a script; returns the ground truth reconstruction fields."""
    inputs, options = scripted_inputs(script, fps, duration)
    out = simulate(inputs, **options)
    num_frames = out.hand_pos.shape[1]
    K = len(script.static_pos)
    n = lambda x: x[0].detach().numpy()  # noqa: E731
    return {
        "fps": np.array(fps),
        "t": np.arange(num_frames) / fps,
        "hand_pos": n(out.hand_pos),
        "hand_rot": n(out.hand_rot),
        "grasp": n(out.grasp),
        "grasped": n(out.grasped),
        "object_pos": n(out.object_pos),
        "object_rot": n(out.object_rot),
        "object_size": script.object_size,
        "static_pos": script.static_pos.reshape(K, 3),
        "static_rot": _static_rotations(script),
        "static_size": script.static_size.reshape(K, 3),
        "camera_elevation": np.array(script.camera_elevation),
        "camera_height": np.array(script.camera_height),
        "loss": np.array(0.0),
    }


def _render(truth: dict[str, np.ndarray], intrinsics: Intrinsics) -> np.ndarray:
    """Exact visible masks (N, 2 + K, H, W) of the true scene."""
    cuboid_pos, cuboid_rot, cuboid_size = scene_cuboids(SimpleNamespace(**truth))
    return raycast_masks(
        truth["hand_pos"],
        truth["hand_rot"],
        cuboid_pos,
        cuboid_rot,
        cuboid_size,
        float(truth["camera_height"]),
        float(truth["camera_elevation"]),
        intrinsics,
    )


def _in_view(masks: np.ndarray, margin: int = 2, *, partly: bool = False) -> bool:
    """Whether every cuboid stays inside the image (not touching its border) and is seen.

    ``partly``: the object need only be inside the image until it is grasped (it may then
    leave the view with the hand), and static boxes may be cut by the frame.
    """
    cuboids = masks[:, 1:]
    border = np.zeros(masks.shape[-2:], bool)
    border[:margin], border[-margin:], border[:, :margin], border[:, -margin:] = True, True, True, True
    if partly:
        cuboids = cuboids[: max(1, len(cuboids) // 3), :1]
    touches = (cuboids & border).any()
    seen = cuboids.reshape(*cuboids.shape[:2], -1).any(-1)
    return not touches and seen[:, 0].mean() > 0.8 and masks[:, 0].any()


def _noisy_masks(masks: np.ndarray, noise: Noise, rng: np.random.Generator, *, drop: bool) -> np.ndarray:
    """Masks (N, H, W) with jittered boundaries, spurious blobs and (if ``drop``) lost frames."""
    out = masks.astype(np.uint8)
    H, W = out.shape[1:]
    for k in range(len(out)):
        if noise.jitter:
            r = int(rng.integers(-noise.jitter, noise.jitter + 1))
            if r:
                kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * abs(r) + 1, 2 * abs(r) + 1))
                out[k] = (cv2.dilate if r > 0 else cv2.erode)(out[k], kernel)
        if rng.random() < noise.blob_rate:
            centre = (int(rng.integers(0, W)), int(rng.integers(0, H)))
            axes = (int(rng.integers(2, 8)), int(rng.integers(2, 8)))
            cv2.ellipse(out[k], centre, axes, float(rng.uniform(0, 180)), 0, 360, 1, -1)
        if drop and rng.random() < noise.missing_rate:
            out[k] = 0
    if not out.any():  # never lose every frame of a mask
        out = masks.astype(np.uint8)
    return out.astype(bool)


def _noisy_contact(contact: np.ndarray, noise: Noise, rng: np.random.Generator) -> np.ndarray:
    """A contact signal whose onset and release move by up to ``contact_shift`` frames, with flips."""
    out = contact.copy()
    on = np.flatnonzero(contact)
    if noise.contact_shift and len(on):
        first = int(np.clip(on[0] + rng.integers(-noise.contact_shift, noise.contact_shift + 1), 0, len(out) - 1))
        last = int(np.clip(on[-1] + rng.integers(-noise.contact_shift, noise.contact_shift + 1), first, len(out) - 1))
        out[:] = False
        out[first : last + 1] = True
    for k in rng.choice(len(out), size=noise.contact_flips, replace=False):
        out[k] = ~out[k]
    if not out.any():
        out = contact.copy()
    return out
