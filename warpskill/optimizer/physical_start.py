"""Where stage (b) starts: the hand's velocity spline and the initial poses, from stage (a)'s fit.

Stage (a) places hand and object anew in every frame; the physics stage integrates a hand
velocity spline instead. These functions turn the per-frame fit into that spline's knots
and into initial poses the engine can start from (the hand's tip inside the object at the
first contact, the object out of every static box), and return what they compute: the
caller (:class:`~warpskill.optimizer.stage_b.PhysicalScene`) only registers it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from warpskill.engine.distances import box_signed_distance, static_exits
from warpskill.engine.rotations import rotation_log, rotation_to_6d
from warpskill.optimizer.scene import SceneTrajectories
from warpskill.optimizer.spline import natural_cubic_basis

CONTACT_FIT_WEIGHT = 50.0  # contact frames' weight in the hand spline's least-squares fit
MAX_ONSET_SHIFT = 0.02  # [m] largest shift of the hand path that puts the tip inside at the onset
START_CLEARANCE = 0.002  # [m] left between an object moved out of a static box and its face
_ACROSS = torch.tensor([1.0, 1.0, 0.0])  # keeps a displacement's horizontal part (world z is up)
MISFIT_WINDOW = 4  # frames on each side of the running median of stage (a)'s hand loss
MISFIT_SCALE = 0.2  # hand dIoU above that median at which a frame's weight in the spline's fit falls to 1/e


@dataclass(frozen=True)
class SplineTiming:
    """The hand's velocity spline over a video of ``num_frames`` frames at ``fps`` [1/s],
    integrated in ``steps_per_frame`` engine steps per frame with ``num_knots`` knots."""

    num_frames: int
    fps: float
    steps_per_frame: int
    num_knots: int

    @classmethod
    def of(cls, num_frames: int, fps: float, steps_per_frame: int, knots_per_second: float) -> SplineTiming:
        """The timing of a video, with at least 4 knots and about ``knots_per_second``."""
        duration = (num_frames - 1) / fps
        return cls(num_frames, float(fps), steps_per_frame, max(4, round(duration * knots_per_second) + 1))

    @property
    def duration(self) -> float:
        """[s] from the first frame to the last."""
        return (self.num_frames - 1) / self.fps

    @property
    def dt(self) -> float:
        """[s] one engine step."""
        return 1.0 / (self.fps * self.steps_per_frame)

    def step_basis(self) -> np.ndarray:
        """(S, knots) the spline's basis at every engine step of the video."""
        step_times = np.arange((self.num_frames - 1) * self.steps_per_frame) * self.dt
        return natural_cubic_basis(self.num_knots, self.duration, step_times)

    def frame_basis(self) -> np.ndarray:
        """(N, knots) the spline's basis at the video's frames."""
        return natural_cubic_basis(self.num_knots, self.duration, np.arange(self.num_frames) / self.fps)


@dataclass(frozen=True)
class PhysicalStart:
    """Stage (b)'s initial values (CPU tensors).

    Attributes:
        hand_rot6: (6,) the hand's first rotation, 6-D representation.
        grasp0: 0-d the grasp signal's first value [m].
        control: (knots, 7) knot velocities: linear [m/s], angular [rad/s], grasp rate [m/s].
        hand_pos0: (3,) [m] the hand's first position.
        object_pos0: (3,) [m] the object's first position.
        object_rot6: (6,) the object's first rotation, 6-D representation.
    """

    hand_rot6: torch.Tensor
    grasp0: torch.Tensor
    control: torch.Tensor
    hand_pos0: torch.Tensor
    object_pos0: torch.Tensor
    object_rot6: torch.Tensor


def physical_start(
    fit: SceneTrajectories, contact: np.ndarray, timing: SplineTiming, *, knots_per_second: float,
    grasp_level: float, unseen_before_contact: bool = False, hand_loss: np.ndarray | None = None,
) -> PhysicalStart:
    """Stage (b)'s initial values from stage (a)'s per-frame ``fit`` (on the CPU) over N frames.

    Args:
        fit: per-frame trajectories of stage (a).
        contact: (N,) bool contact signal.
        timing: the hand spline's timing over the N frames.
        knots_per_second: the spline's knot density (the grasp window's lead is half a knot
            interval).
        grasp_level: |g| [m] the grasp signal starts at, positive in contact frames and half a
            knot interval before them (:func:`grasp_window`).
        unseen_before_contact: the object's mask is empty in every frame before the first
            contact frame (it was carried into the view).
        hand_loss: (N,) stage (a)'s hand dIoU per frame (None: every frame fits alike); the
            hand spline's fit weighs frames by :func:`isolated_misfit_weights` of it.
    """
    N = timing.num_frames
    if hand_loss is not None and np.shape(hand_loss) != (N,):
        raise ValueError(f"hand_loss must be ({N},), one value per frame of the fit, got {np.shape(hand_loss)}")
    # A spline fitted to a step crosses zero at the step: opened early, the signal is near its
    # level when the tip enters, and the switch closes fully.
    lead = math.ceil(0.5 * timing.fps / knots_per_second)
    grasp_target = torch.where(torch.as_tensor(grasp_window(contact, lead)), grasp_level, -grasp_level)
    frame_weight = np.ones(N) if hand_loss is None else isolated_misfit_weights(hand_loss)
    basis = timing.step_basis()
    control = fit_hand_control(fit, contact, frame_weight, grasp_target, basis, timing)
    gap, normal = grasp_onset_gap(fit, contact, control, basis, timing, grasp_level)
    # A correction for the spline's error, not a relocation: far from the object, stage (a)
    # itself disagrees with the contact signal, and moving the whole path would undo its fit.
    shift = gap.clamp(0.0, MAX_ONSET_SHIFT)
    # The rest of the gap moves the object, as far as stage (a) itself moved it before the
    # grasp (the engine keeps an untouched object where it starts; stage (a) only asks it
    # to rest), and only across its support: lifted, a resting object would fall before
    # the hand reaches it. Anywhere for an object the masks never saw before the grasp
    # (carried into the view), where the hand first takes it.
    if unseen_before_contact:
        move = (gap - shift) * normal
    else:
        move = (gap - shift).clamp(max=_drift_before_contact(fit, contact)) * normal * _ACROSS
    return PhysicalStart(
        hand_rot6=rotation_to_6d(fit.hand_rot[0]),
        grasp0=grasp_target[0].reshape(()).clone(),
        control=control,
        hand_pos0=fit.hand_pos[0] - shift * normal,
        object_pos0=clear_of_statics(fit.object_pos[0] + move, fit.object_rot[0], fit.object_size,
                                     fit.static_pos, fit.static_rot, fit.static_size),
        object_rot6=rotation_to_6d(fit.object_rot[0]),
    )


def fit_hand_control(
    fit: SceneTrajectories, contact: np.ndarray, frame_weight: np.ndarray, grasp_target: torch.Tensor,
    basis: np.ndarray, timing: SplineTiming,
) -> torch.Tensor:
    """Knot velocities (knots, 7) that reproduce stage (a)'s hand motion and the contact.

    Positions and the grasp signal are integrals of the spline, linear in the knots, so
    they are fitted in least squares on their integrated basis (``basis``: (S, knots) at the
    engine's steps); contact frames weigh more, because the tip must be inside the object
    there for the grasp to engage, and positions are weighed by ``frame_weight`` (N,)
    besides. Angular velocities are fitted to the frame-to-frame rotations.
    """
    spf, N, fps = timing.steps_per_frame, timing.num_frames, timing.fps
    cumulative = np.concatenate([np.zeros((1, basis.shape[1])), np.cumsum(basis, 0) * timing.dt])[::spf]  # (N, knots)
    ridge = 1e-6 * np.eye(basis.shape[1])
    weight = np.sqrt(frame_weight * (1.0 + CONTACT_FIT_WEIGHT * np.asarray(contact, dtype=float)))[:, None]

    def solve(design: np.ndarray, rhs: np.ndarray, w: np.ndarray | float = 1.0) -> np.ndarray:
        design, rhs = w * design, w * rhs
        return np.linalg.solve(design.T @ design + ridge, design.T @ rhs)

    pos = fit.hand_pos.double().numpy()
    linear = solve(cumulative, pos - pos[0], weight)
    grasp = grasp_target.double().numpy()
    grasp_rate = solve(cumulative, (grasp - grasp[0])[:, None])
    R = fit.hand_rot.double()
    omega = rotation_log(R[1:] @ R[:-1].transpose(-1, -2)).numpy() * fps  # (N - 1, 3)
    mid_times = (np.arange(N - 1) + 0.5) / fps
    mid_basis = natural_cubic_basis(basis.shape[1], (N - 1) / fps, mid_times)
    angular = solve(mid_basis, omega)
    return torch.as_tensor(np.concatenate([linear, angular, grasp_rate], 1), dtype=torch.float32)


def grasp_onset_gap(
    fit: SceneTrajectories, contact: np.ndarray, control: torch.Tensor, basis: np.ndarray, timing: SplineTiming,
    depth: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """How far [m] (0-d, >= 0) the simulated hand tip is from being ``depth`` inside the
    object at the first contact frame, and along which normal (3,) of the object.

    The spline only approximates stage (a)'s hand path, and stage (a) only asks for the
    tip to be inside on average; millimetres decide whether the grasp switch saturates
    (the latched switch holds what it reached, and one below 1 carries the object only
    partly, lagging the hand). Moving the tip by ``-gap * normal`` (or the object by
    ``+gap * normal``) closes it, along the normal of the object's face nearest to the
    tip; once the grasp closes, the rigid carry keeps the depth.
    """
    onset = np.flatnonzero(contact)
    if len(onset) == 0:
        return torch.zeros(()), torch.zeros(3)
    steps = int(onset[0]) * timing.steps_per_frame
    tip = fit.hand_pos[0] + timing.dt * torch.as_tensor(basis[:steps].sum(0), dtype=torch.float32) @ control[:, :3]
    pos, rot, size = fit.object_pos[0], fit.object_rot[0], fit.object_size
    local = rot.T @ (tip - pos)
    axis = int(torch.argmax(local.abs() - 0.5 * size))
    normal = rot[:, axis] * torch.sign(local[axis])
    depth = min(depth, 0.25 * float(size.min()))
    distance = box_signed_distance(tip, pos, rot, size)
    return (distance + depth).clamp_min(0.0), normal


def isolated_misfit_weights(hand_loss: np.ndarray) -> np.ndarray:
    """Weights (N,) in (0, 1] of the frames in the hand spline's fit, from stage (a)'s hand
    dIoU per frame ``hand_loss`` (N,): ``exp(-(excess / MISFIT_SCALE)^2)``, the excess being
    the loss above its running median over 2 MISFIT_WINDOW + 1 frames.

    Stage (a) places the hand anew in every frame; where it could not match one or two
    frames' hand masks (an ambiguous silhouette), its path jumps there, and the physics
    stage, which stays near the spline it starts from, would keep the jump. An isolated
    misfit barely pulls the spline; a long stretch of poor fit (a cylinder against a real
    hand's box) is the video's norm and keeps its weight.
    """
    loss = np.asarray(hand_loss, dtype=float)
    if loss.ndim != 1 or not np.isfinite(loss).all():
        raise ValueError(f"hand_loss must be (N,) finite values, got shape {loss.shape}")
    window = np.lib.stride_tricks.sliding_window_view(np.pad(loss, MISFIT_WINDOW, mode="edge"), 2 * MISFIT_WINDOW + 1)
    excess = (loss - np.median(window, axis=-1)).clip(min=0.0)
    return np.exp(-((excess / MISFIT_SCALE) ** 2))


def clear_of_statics(pos: torch.Tensor, rot: torch.Tensor, size: torch.Tensor, static_pos: torch.Tensor,
                     static_rot: torch.Tensor, static_size: torch.Tensor) -> torch.Tensor:
    """The object's centre ``pos`` (3,) [m] moved out of every static box its box overlaps, by
    the shortest way out: across a side face, or up onto the top (:func:`static_exits`).

    Stage (a) only asks the object to stay out of the static boxes; the engine makes it, and an
    object started inside one is pushed out at once, knocked away from where the masks put it.
    ``rot`` (3, 3), ``size`` (3,); statics (K, 3), (K, 3, 3) yawed only, (K, 3).
    """
    for k in range(len(static_pos)):
        exits = static_exits(pos, rot, size, static_pos[k : k + 1], static_rot[k : k + 1], static_size[k : k + 1])[0]
        if bool((exits > 0).all()):
            way = int(torch.argmin(exits))
            step = pos.new_zeros(3)
            step[way // 2] = (exits[way] + START_CLEARANCE) * (-1.0 if way in (1, 3) else 1.0)
            pos = pos + static_rot[k] @ step
    return pos


def grasp_window(contact: np.ndarray, lead: int) -> np.ndarray:
    """(N,) bool: the ``contact`` (N,) frames and the ``lead`` frames before each run of them."""
    window = np.asarray(contact, dtype=bool).copy()
    for onset in np.flatnonzero(np.diff(np.concatenate([[False], window])) > 0):
        window[max(0, onset - lead) : onset] = True
    return window


def _drift_before_contact(fit: SceneTrajectories, contact: np.ndarray) -> float:
    """How far [m] stage (a)'s object centre is, at the first contact frame, from where it
    starts (0 without contact)."""
    onset = np.flatnonzero(contact)
    if len(onset) == 0:
        return 0.0
    return float(torch.linalg.vector_norm(fit.object_pos[onset[0]] - fit.object_pos[0]))
