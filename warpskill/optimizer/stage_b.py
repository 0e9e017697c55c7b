"""Stage (b) parameters: a scene whose trajectories come from the physics engine.

The optimised quantities are the paper's: the hand's initial pose and grasp signal and its
velocity spline (v, w, g' at the knots), the object's initial pose and size, the static
cuboids' ground position, yaw and size, and the camera's height and elevation. Every
trajectory is a rollout of :func:`warpskill.engine.simulation.simulate`, preceded by a pre-roll and
followed by a post-roll in which the hand holds still, so the objective can ask the object
to be at rest before and after the video.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from warpskill.engine.distances import box_signed_distance, static_exits
from warpskill.engine.records import Rollout, SceneInputs
from warpskill.engine.rotations import rotation_from_6d, rotation_log, rotation_to_6d
from warpskill.engine.simulation import PhysicsConfig, simulate, substeps_per_frame
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.known import pin_sizes
from warpskill.optimizer.losses import MaskTargets
from warpskill.optimizer.scene import (
    SceneShape,
    SceneTrajectories,
    perceptual_loss,
    scene_priors,
    static_poses,
)
from warpskill.optimizer.spline import natural_cubic_basis
from warpskill.optimizer.weights import LossWeights

CONTACT_FIT_WEIGHT = 50.0  # contact frames' weight in the hand spline's least-squares fit
MAX_ONSET_SHIFT = 0.02  # [m] largest shift of the hand path that puts the tip inside at the onset
START_CLEARANCE = 0.002  # [m] left between an object moved out of a static box and its face
_ACROSS = torch.tensor([1.0, 1.0, 0.0])  # keeps a displacement's horizontal part (world z is up)
MISFIT_WINDOW = 4  # frames on each side of the running median of stage (a)'s hand loss
MISFIT_SCALE = 0.2  # hand dIoU above that median at which a frame's weight in the spline's fit falls to 1/e


@dataclass
class PhysicalRollout:
    """A rollout split into the video's frames and the still frames around it.

    Attributes:
        scene: per-frame scene over the video's N frames.
        rollout: the engine's per-frame output over the video's N frames.
        still_velocity: (P,) squared object speed (linear [m/s] plus angular [rad/s]) in
            the pre- and post-roll frames.
        hand_speed: (N,) squared hand speed from the spline at the video's frames.
    """

    scene: SceneTrajectories
    rollout: Rollout
    still_velocity: torch.Tensor
    hand_speed: torch.Tensor


class PhysicalScene(SceneShape):
    """Stage (b) parameters, initialised from stage (a)'s per-frame fit.

    Args:
        fit: per-frame trajectories of stage (a) over N frames.
        contact: (N,) bool contact signal.
        fps: frame rate [1/s].
        knots_per_second: density of the hand's velocity spline.
        pre_roll, post_roll: still time [s] simulated before and after the video.
        grasp_level: |g| [m] the grasp signal starts at, positive in contact frames and half a
            knot interval before them (:func:`grasp_window`).
        physics: engine constants.
        known: lengths held at their values (:data:`warpskill.optimizer.known.KNOWN_LENGTHS`).
        unseen_before_contact: the object's mask is empty in every frame before the first
            contact frame (it was carried into the view).
        hand_loss: (N,) stage (a)'s hand dIoU per frame (None: every frame fits alike); the
            hand spline's fit weighs frames by :func:`isolated_misfit_weights` of it.
    """

    def __init__(
        self,
        fit: SceneTrajectories,
        contact: np.ndarray,
        fps: float,
        *,
        knots_per_second: float,
        pre_roll: float,
        post_roll: float,
        grasp_level: float,
        physics: PhysicsConfig,
        known: dict[str, float] | None = None,
        unseen_before_contact: bool = False,
        hand_loss: np.ndarray | None = None,
    ):
        super().__init__()
        self.known = dict(known or {})
        self.physics = physics
        self.fps = float(fps)
        self.num_frames = N = fit.hand_pos.shape[0]
        self.steps_per_frame = substeps_per_frame(fps, physics)
        self.pre_frames = math.ceil(pre_roll * fps)
        self.post_frames = math.ceil(post_roll * fps)
        duration = (N - 1) / fps
        num_knots = max(4, round(duration * knots_per_second) + 1)
        dt = 1.0 / (fps * self.steps_per_frame)
        step_times = np.arange((N - 1) * self.steps_per_frame) * dt
        basis = natural_cubic_basis(num_knots, duration, step_times)  # (S, knots)
        self.register_buffer("step_basis", torch.as_tensor(basis, dtype=torch.float32))
        frame_times = np.arange(N) / fps
        self.register_buffer(
            "frame_basis", torch.as_tensor(natural_cubic_basis(num_knots, duration, frame_times), dtype=torch.float32)
        )

        P = torch.nn.Parameter
        fit = fit.detached("cpu")
        # A spline fitted to a step crosses zero at the step: opened early, the signal is near its
        # level when the tip enters, and the switch closes fully.
        lead = math.ceil(0.5 * self.fps / knots_per_second)
        grasp_target = torch.where(torch.as_tensor(grasp_window(contact, lead)), grasp_level, -grasp_level)
        self.hand_rot6 = P(rotation_to_6d(fit.hand_rot[0]))
        self.grasp0 = P(grasp_target[0].reshape(()).clone())
        if hand_loss is not None and np.shape(hand_loss) != (N,):
            raise ValueError(f"hand_loss must be ({N},), one value per frame of the fit, got {np.shape(hand_loss)}")
        frame_weight = np.ones(N) if hand_loss is None else isolated_misfit_weights(hand_loss)
        control = self._fit_control(fit, contact, frame_weight, grasp_target, basis, dt)
        self.control = P(control)
        gap, normal = self._grasp_onset_gap(fit, contact, control, basis, dt, grasp_level)
        # A correction for the spline's error, not a relocation: far from the object, stage (a)
        # itself disagrees with the contact signal, and moving the whole path would undo its fit.
        shift = gap.clamp(0.0, MAX_ONSET_SHIFT)
        self.hand_pos0 = P(fit.hand_pos[0] - shift * normal)
        # The rest of the gap moves the object, as far as stage (a) itself moved it before the
        # grasp (the engine keeps an untouched object where it starts; stage (a) only asks it
        # to rest), and only across its support: lifted, a resting object would fall before
        # the hand reaches it. Anywhere for an object the masks never saw before the grasp
        # (carried into the view), where the hand first takes it.
        if unseen_before_contact:
            move = (gap - shift) * normal
        else:
            move = (gap - shift).clamp(max=_drift_before_contact(fit, contact)) * normal * _ACROSS
        self.object_pos0 = P(clear_of_statics(fit.object_pos[0] + move, fit.object_rot[0], fit.object_size,
                                              fit.static_pos, fit.static_rot, fit.static_size))
        self.object_rot6 = P(rotation_to_6d(fit.object_rot[0]))
        self.register_shape(fit)

    def _fit_control(
        self, fit: SceneTrajectories, contact: np.ndarray, frame_weight: np.ndarray, grasp_target: torch.Tensor,
        basis: np.ndarray, dt: float,
    ) -> torch.Tensor:
        """Knot velocities (knots, 7) that reproduce stage (a)'s hand motion and the contact.

        Positions and the grasp signal are integrals of the spline, linear in the knots, so
        they are fitted in least squares on their integrated basis; contact frames weigh
        more, because the tip must be inside the object there for the grasp to engage, and
        positions are weighed by ``frame_weight`` (N,) besides. Angular velocities are fitted
        to the frame-to-frame rotations.
        """
        spf = self.steps_per_frame
        N = self.num_frames
        cumulative = np.concatenate([np.zeros((1, basis.shape[1])), np.cumsum(basis, 0) * dt])[::spf]  # (N, knots)
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
        omega = rotation_log(R[1:] @ R[:-1].transpose(-1, -2)).numpy() * self.fps  # (N - 1, 3)
        mid_times = (np.arange(N - 1) + 0.5) / self.fps
        mid_basis = natural_cubic_basis(basis.shape[1], (N - 1) / self.fps, mid_times)
        angular = solve(mid_basis, omega)
        return torch.as_tensor(np.concatenate([linear, angular, grasp_rate], 1), dtype=torch.float32)

    def _grasp_onset_gap(
        self, fit: SceneTrajectories, contact: np.ndarray, control: torch.Tensor, basis: np.ndarray, dt: float,
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
        steps = int(onset[0]) * self.steps_per_frame
        tip = fit.hand_pos[0] + dt * torch.as_tensor(basis[:steps].sum(0), dtype=torch.float32) @ control[:, :3]
        pos, rot, size = fit.object_pos[0], fit.object_rot[0], fit.object_size
        local = rot.T @ (tip - pos)
        axis = int(torch.argmax(local.abs() - 0.5 * size))
        normal = rot[:, axis] * torch.sign(local[axis])
        depth = min(depth, 0.25 * float(size.min()))
        distance = box_signed_distance(tip, pos, rot, size)
        return (distance + depth).clamp_min(0.0), normal

    def cuboids(self) -> tuple[torch.Tensor, ...]:
        """Object size (3,), static centres (K, 3), rotations (K, 3, 3) and sizes (K, 3)."""
        object_size, static_size, _ = self.free_sizes()
        object_size, static_size, _ = pin_sizes(self.known, object_size, static_size, self.camera_height())
        static_pos, static_rot = static_poses(self.static_xy, self.static_yaw, static_size)
        return object_size, static_pos, static_rot, static_size

    def camera_height(self) -> torch.Tensor:
        """The camera's height [m] (the known one, when given)."""
        height = self.free_sizes()[2]
        return torch.full_like(height, self.known["camera_height"]) if "camera_height" in self.known else height

    def simulation_inputs(self) -> SceneInputs:
        """The rollout inputs of this scene (B = 1): pre-roll, the video, post-roll; simulate
        them with :meth:`simulation_options`."""
        object_size, static_pos, static_rot, static_size = self.cuboids()
        spf = self.steps_per_frame
        main_velocity = self.step_basis @ self.control  # (S, 7)
        still = lambda frames: main_velocity.new_zeros(frames * spf, 7)  # noqa: E731
        hand_velocity = torch.cat([still(self.pre_frames), main_velocity, still(self.post_frames)])
        return SceneInputs(
            hand_pos0=self.hand_pos0[None],
            hand_rot0=rotation_from_6d(self.hand_rot6)[None],
            grasp0=self.grasp0.reshape(1),
            hand_vel=hand_velocity[None],
            object_pos0=self.object_pos0[None],
            object_rot0=rotation_from_6d(self.object_rot6)[None],
            object_size=object_size[None],
            static_pos=static_pos[None],
            static_rot=static_rot[None],
            static_size=static_size[None],
        )

    def simulation_options(self) -> dict:
        """The keyword arguments ``steps_per_frame``, ``fps`` [1/s] and ``config`` of
        :func:`warpskill.engine.simulation.simulate` for this scene."""
        return dict(steps_per_frame=self.steps_per_frame, fps=self.fps, config=self.physics)

    def assemble(self, out: Rollout) -> PhysicalRollout:
        """This scene's :class:`PhysicalRollout` from the rollout (B = 1) of its :meth:`simulation_inputs`."""
        object_size, static_pos, static_rot, static_size = self.cuboids()
        video = slice(self.pre_frames, self.pre_frames + self.num_frames)
        rollout = out.map(lambda value: value[0, video])
        speed = out.object_vel[0].square().sum(-1) + out.object_ang_vel[0].square().sum(-1)
        still_velocity = torch.cat([speed[: self.pre_frames + 1], speed[self.pre_frames + self.num_frames :]])
        frame_velocity = self.frame_basis @ self.control
        scene = SceneTrajectories(
            hand_pos=rollout.hand_pos,
            hand_rot=rollout.hand_rot,
            object_pos=rollout.object_pos,
            object_rot=rollout.object_rot,
            object_size=object_size,
            static_pos=static_pos,
            static_rot=static_rot,
            static_size=static_size,
            camera_height=self.camera_height(),
            camera_elevation=self.camera_elevation,
        )
        return PhysicalRollout(scene, rollout, still_velocity, frame_velocity[:, :6].square().sum(-1))

    def forward(self, simulate=simulate) -> PhysicalRollout:
        """Simulate the scene (pre-roll, the video, post-roll) with ``simulate`` (default: the Warp engine)."""
        return self.assemble(simulate(self.simulation_inputs(), **self.simulation_options()))


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


def make_physical_scene(
    fit: SceneTrajectories, contact_signal: np.ndarray, fps: float, config: OptimizeConfig,
    known: dict[str, float] | None = None, unseen_before_contact: bool = False, hand_loss: np.ndarray | None = None,
) -> PhysicalScene:
    """Stage (b)'s parameters started from the per-frame scene ``fit`` (on the CPU), ``known`` lengths held
    (``unseen_before_contact``, ``hand_loss``: see :class:`PhysicalScene`)."""
    return PhysicalScene(
        fit,
        contact_signal,
        fps,
        knots_per_second=config.knots_per_second,
        pre_roll=config.pre_roll,
        post_roll=config.post_roll,
        grasp_level=2.0 * config.weights.grasp_margin,
        physics=config.physics,
        known=known,
        unseen_before_contact=unseen_before_contact,
        hand_loss=hand_loss,
    )


def physical_objective(
    result: PhysicalRollout,
    rendered: torch.Tensor,
    targets: MaskTargets,
    contact: torch.Tensor,
    object_visible: torch.Tensor,
    weights: LossWeights,
    supported: torch.Tensor | None = None,
    behind: torch.Tensor | None = None,
    typical_edges: tuple[float, float, float] | None = None,
) -> dict[str, torch.Tensor]:
    """Stage (b) loss terms: perceptual, velocity regularisation, contact, stability, and the
    placement "on the static" where it is the hypothesis.

    Args:
        result: the simulated scene.
        rendered: (N, 2 + K, h, w) its soft silhouettes at the working resolution, or their
            :class:`~warpskill.optimizer.losses.MaskProfile` against ``targets``.
        targets: (N, 2 + K, h, w) masks at the working resolution.
        contact: (N,) contact signal in {0, 1}.
        object_visible: (N,) 1 where the object's mask is not empty.
        weights: loss weights.
        supported: (N,) 1 in frames where the object is to stand on the first static box
            (the placement whose physics is being tried); None: no such placement.
        behind: (N,) 1 in frames where the first static box hides the object's lower part:
            the object is asked to stand behind the box's back; None: no such frames.
        typical_edges: [m] the edges, ascending, of the object's noun's typical size, where its
            prior applies (:func:`~warpskill.optimizer.scene.noun_size_prior`); None: no such prior.

    Returns:
        Named weighted terms; the loss is their sum.
    """
    rollout = result.rollout
    object_speed = rollout.object_vel.square().sum(-1) + rollout.object_ang_vel.square().sum(-1)
    margin = weights.grasp_margin
    return {
        "perceptual": perceptual_loss(rendered, targets, weights),
        "hand velocity": weights.hand_velocity * result.hand_speed.mean(),
        "hidden object velocity": weights.invisible_object_velocity * ((1 - object_visible) * object_speed).mean(),
        "contact distance": weights.contact_distance
        * (contact * (rollout.tip_distance + margin).clamp_min(0.0) ** 2).mean(),
        "grasp": weights.grasp
        * (
            (contact * (margin - rollout.grasp).clamp_min(0.0) ** 2).mean()
            + ((1 - contact) * (rollout.grasp + margin).clamp_min(0.0) ** 2).mean()
        ),
        "stability": weights.stability * result.still_velocity.mean(),
    } | scene_priors(result.scene, weights, supported, behind, whole_object_behind=True, typical_edges=typical_edges)
