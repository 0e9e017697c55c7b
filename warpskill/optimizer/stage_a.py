"""Stage (a) of the optimisation: a physics-free fit of per-frame poses to the masks.

Per frame it places the hand and the object freely (no dynamics), together with the object
size, the static cuboids and the camera's height and elevation, minimising the perceptual
dIoU, the hand-tip-to-object distance in contact frames and a smoothness prior. It starts
from :func:`warpskill.optimizer.guess.initial_guess`; its result is a first camera and first
trajectories for the physics stage (:mod:`warpskill.optimizer.stage_b`).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from warpskill.engine.distances import (
    box_signed_distance,
    lowest_corner_height,
    static_overlap_depth,
    support_height,
)
from warpskill.engine.rotations import rotation_from_6d, rotation_to_6d, yaw_rotation
from warpskill.optimizer.known import measured, pin_sizes
from warpskill.optimizer.losses import MaskTargets
from warpskill.optimizer.scene import (
    SceneShape,
    SceneTrajectories,
    perceptual_loss,
    scene_priors,
    static_poses,
)
from warpskill.optimizer.weights import LossWeights

FREE_MARGIN_FRAMES = 2  # frames next to a contact frame that the resting priors ignore


class InitialParameters(SceneShape):
    """Free per-frame parameters of stage (a), initialised from a :class:`SceneTrajectories`.

    The object stays upright (it turns about z only): an upright box shows as much of its
    top face as the camera's elevation dictates, which makes the elevation observable.
    A global scale multiplies every position, size and the camera height: scaling the
    whole scene about the camera changes only the hand's apparent width (its size is
    fixed), a direction too flat for per-frame parameters to follow one by one.

    ``known`` lengths (:data:`warpskill.optimizer.known.KNOWN_LENGTHS` -> metres) replace that
    scale: it is whatever makes the first of them come out at its value, and the others
    are put in exactly.
    """

    def __init__(self, guess: SceneTrajectories, known: dict[str, float] | None = None):
        super().__init__()
        self.known = dict(known or {})
        P = torch.nn.Parameter
        self.hand_pos = P(guess.hand_pos.clone())
        self.hand_rot6 = P(rotation_to_6d(guess.hand_rot))
        self.object_pos = P(guess.object_pos.clone())
        self.object_yaw = P(torch.atan2(guess.object_rot[:, 1, 0], guess.object_rot[:, 0, 0]))
        self.register_shape(guess)
        self.log_scale = P(torch.zeros(()))

    def scene(self) -> SceneTrajectories:
        """The per-frame scene these parameters describe."""
        object_size, static_size, camera_height = self.free_sizes()
        scale = self.log_scale.exp()
        for name, value in self.known.items():
            unscaled = measured(name, object_size, static_size, camera_height)
            if unscaled is not None:
                scale = value / unscaled
                break
        object_size, static_size, camera_height = pin_sizes(
            self.known, scale * object_size, scale * static_size, scale * camera_height
        )
        static_pos, static_rot = static_poses(scale * self.static_xy, self.static_yaw, static_size)
        return SceneTrajectories(
            hand_pos=scale * self.hand_pos,
            hand_rot=rotation_from_6d(self.hand_rot6),
            object_pos=scale * self.object_pos,
            object_rot=yaw_rotation(self.object_yaw),
            object_size=object_size,
            static_pos=static_pos,
            static_rot=static_rot,
            static_size=static_size,
            camera_height=camera_height,
            camera_elevation=self.camera_elevation,
        )


def far_from_contact(contact: torch.Tensor, margin: int) -> torch.Tensor:
    """(N,) 1 in frames more than ``margin`` frames away from any contact frame, else 0.

    Contact signals are off by a frame or two around the onset and release; the resting
    priors trust only the frames that are clearly free.
    """
    near = torch.nn.functional.max_pool1d(contact[None, None], 2 * margin + 1, stride=1, padding=margin)[0, 0]
    return 1.0 - near


def initial_objective(
    scene: SceneTrajectories,
    rendered: torch.Tensor,
    targets: MaskTargets,
    contact: torch.Tensor,
    fps: float,
    weights: LossWeights,
    uncertain: torch.Tensor | None = None,
    supported: torch.Tensor | None = None,
    behind: torch.Tensor | None = None,
    typical_edges: tuple[float, float, float] | None = None,
    static_edges: Sequence[tuple[float, float, float] | None] = (),
) -> dict[str, torch.Tensor]:
    """Stage (a) loss terms: perceptual, contact distance, smoothness and resting priors.

    Args:
        scene: the per-frame scene.
        rendered: (N, 2 + K, h, w) its soft silhouettes at the working resolution, or their
            :class:`~warpskill.optimizer.losses.MaskProfile` against ``targets``.
        targets: the masks at the working resolution.
        contact: (N,) contact signal in {0, 1}.
        fps: frame rate [1/s].
        weights: loss weights.
        uncertain: (N,) 1 in frames whose contact is in doubt (the object may still be held
            after the signal ends): neither the contact nor the resting priors apply there.
        supported: (N,) 1 in frames where the object stands on the first static box (the
            hypothesis "on the static"): its centre is asked to lie over the box's footprint.
        behind: (N,) 1 in frames where the first static box hides the object's lower part
            (:func:`warpskill.optimizer.inputs.cut_by_static`): its centre is asked to lie
            behind the box's back.
        typical_edges: [m] the edges, ascending, of the object's noun's typical size, where its
            prior applies (:func:`~warpskill.optimizer.scene.noun_size_prior`); None: no such prior.
        static_edges: the same per static object (None where none applies; empty: none at all).
    """
    tip_distance = box_signed_distance(scene.hand_pos, scene.object_pos, scene.object_rot, scene.object_size)
    c = contact.to(tip_distance.dtype)
    known_state = 1.0 if uncertain is None else 1.0 - uncertain.to(c)

    def acceleration(x):  # (N, D) -> mean squared second difference [per s^2]
        return ((x[2:] - 2 * x[1:-1] + x[:-2]) * fps**2).square().sum(-1).mean() if len(x) > 2 else x.sum() * 0

    rot6 = rotation_to_6d
    free = far_from_contact(c, FREE_MARGIN_FRAMES) * known_state
    c = c * known_state
    free_steps = free[1:] * free[:-1]
    moved = ((scene.object_pos[1:] - scene.object_pos[:-1]) * fps).square().sum(-1)
    low = lowest_corner_height(scene.object_pos, scene.object_rot, scene.object_size)
    below = (-low).clamp_min(0.0).square().mean() + (-scene.hand_pos[:, 2]).clamp_min(0.0).square().mean()
    inside = static_overlap_depth(scene.object_pos, scene.object_rot, scene.object_size, scene.static_pos,
                                  scene.static_rot, scene.static_size)  # (N, K)
    support = support_height(scene.object_pos, scene.static_pos, scene.static_rot, scene.static_size)
    return {
        "perceptual": perceptual_loss(rendered, targets, weights),
        "contact distance": weights.contact_distance
        * (c * (tip_distance + weights.grasp_margin).clamp_min(0.0) ** 2).mean(),
        "smoothness": weights.smoothness
        * (
            acceleration(scene.hand_pos)
            + acceleration(scene.object_pos)
            + 0.01 * (acceleration(rot6(scene.hand_rot)) + acceleration(rot6(scene.object_rot)))
        ),
        # The object does not move while the hand does not touch it, and rests on what is
        # under it (the ground or a static cuboid's top) ...
        "resting": weights.resting * (free_steps * moved).mean()
        + weights.penetration * (free * (low - support).square()).mean(),
        # ... and nothing goes through the ground, nor the object through a static cuboid
        # (carried across one, it goes over it: the physics would push it up onto the top).
        "penetration": weights.penetration * (below + inside.square().sum(-1).mean()),
    } | scene_priors(scene, weights, supported, behind, typical_edges=typical_edges,
                   static_edges=static_edges)
