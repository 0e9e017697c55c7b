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
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from warpskill.engine.records import Rollout, SceneInputs
from warpskill.engine.rotations import rotation_from_6d
from warpskill.engine.simulation import PhysicsConfig, simulate, substeps_per_frame
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.known import pin_sizes
from warpskill.optimizer.losses import MaskTargets
from warpskill.optimizer.physical_start import SplineTiming, physical_start
from warpskill.optimizer.scene import (
    SceneShape,
    SceneTrajectories,
    perceptual_loss,
    scene_priors,
    static_poses,
)
from warpskill.optimizer.weights import LossWeights


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
        self.num_frames = fit.hand_pos.shape[0]
        self.steps_per_frame = substeps_per_frame(fps, physics)
        self.pre_frames = math.ceil(pre_roll * fps)
        self.post_frames = math.ceil(post_roll * fps)
        timing = SplineTiming.of(self.num_frames, fps, self.steps_per_frame, knots_per_second)
        self.register_buffer("step_basis", torch.as_tensor(timing.step_basis(), dtype=torch.float32))
        self.register_buffer("frame_basis", torch.as_tensor(timing.frame_basis(), dtype=torch.float32))
        fit = fit.detached("cpu")
        start = physical_start(fit, contact, timing, knots_per_second=knots_per_second, grasp_level=grasp_level,
                               unseen_before_contact=unseen_before_contact, hand_loss=hand_loss)
        P = torch.nn.Parameter
        self.hand_rot6 = P(start.hand_rot6)
        self.grasp0 = P(start.grasp0)
        self.control = P(start.control)
        self.hand_pos0 = P(start.hand_pos0)
        self.object_pos0 = P(start.object_pos0)
        self.object_rot6 = P(start.object_rot6)
        self.register_shape(fit)

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
    static_edges: Sequence[tuple[float, float, float] | None] = (),
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
        static_edges: the same per static object (None where none applies; empty: none at all).

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
    } | scene_priors(result.scene, weights, supported, behind, whole_object_behind=True, typical_edges=typical_edges,
                       static_edges=static_edges)
