"""The scene both stages optimise: per-frame hand, object and static cuboids and the camera, in Torch, and its rendering."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch

from warpskill.contract.camera import Intrinsics
from warpskill.engine.primitives import scene_cuboids
from warpskill.engine.rendering import render_silhouettes
from warpskill.engine.rotations import yaw_rotation
from warpskill.optimizer.losses import MaskProfile, MaskTargets, masks_loss
from warpskill.optimizer.weights import LossWeights

MIN_OBJECT_SIZE = 0.01  # [m] the object's smallest size, each axis: a softplus floor that keeps it a solid
MIN_STATIC_SIZE = 0.02  # [m] a static cuboid's smallest size, each axis
MIN_CAMERA_HEIGHT = 0.05  # [m] the camera's lowest height above the ground: it films the table from above


@dataclass
class SceneTrajectories:
    """Per-frame scene: the output of stage (a) and the shape of every reconstruction.

    Tensors: hand_pos (N, 3), hand_rot (N, 3, 3), object_pos (N, 3), object_rot (N, 3, 3),
    object_size (3,), static_pos (K, 3), static_rot (K, 3, 3), static_size (K, 3) [m];
    camera_height [m] and camera_elevation [rad] are 0-d tensors.
    """

    hand_pos: torch.Tensor
    hand_rot: torch.Tensor
    object_pos: torch.Tensor
    object_rot: torch.Tensor
    object_size: torch.Tensor
    static_pos: torch.Tensor
    static_rot: torch.Tensor
    static_size: torch.Tensor
    camera_height: torch.Tensor
    camera_elevation: torch.Tensor

    def detached(self, device: str | torch.device | None = None) -> "SceneTrajectories":
        """A copy with every tensor detached from the autograd graph (and moved to ``device``)."""
        return SceneTrajectories(**{k: v.detach().to(device).clone() for k, v in vars(self).items()})

    def same_as(self, other: "SceneTrajectories") -> bool:
        """Whether every tensor equals ``other``'s exactly (same shapes and values)."""
        return all(torch.equal(v, getattr(other, k)) for k, v in vars(self).items())


def positive(raw: torch.Tensor, minimum: float) -> torch.Tensor:
    """Map unconstrained parameters to values > ``minimum`` (softplus)."""
    return minimum + torch.nn.functional.softplus(raw)


def positive_inverse(value: torch.Tensor, minimum: float) -> torch.Tensor:
    """Inverse of :func:`positive`."""
    x = (torch.as_tensor(value) - minimum).clamp_min(1e-6)
    return x + torch.log(-torch.expm1(-x))


def static_poses(xy: torch.Tensor, yaw: torch.Tensor, size: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """World poses of static cuboids resting on the ground: (K, 3) centres, (K, 3, 3) rotations."""
    pos = torch.cat([xy, 0.5 * size[:, 2:3]], dim=-1)
    return pos, yaw_rotation(yaw)


def perceptual_loss(rendered: torch.Tensor | MaskProfile, targets: MaskTargets, weights: LossWeights) -> torch.Tensor:
    """Weighted mean dIoU over frames: hand, object, then static channels (N, C, h, w), from the
    rendered masks or their :class:`~warpskill.optimizer.losses.MaskProfile`; the channels
    drawn from boxes (``targets.boxed``) compare boxes (:func:`box_loss`), and parts known to
    be out of sight (``targets.absent``) are asked to vanish (:func:`hidden_loss`)."""
    return frame_perceptual_losses(rendered, targets, weights).mean()


def frame_perceptual_losses(rendered: torch.Tensor | MaskProfile, targets: MaskTargets,
                            weights: LossWeights) -> torch.Tensor:
    """:func:`perceptual_loss` per frame, (N,): the channels' weighted dIoU summed."""
    per_mask = masks_loss(rendered, targets)  # (N, C)
    channel_weights = torch.tensor(
        [weights.hand, weights.object] + [weights.static] * (per_mask.shape[1] - 2),
        dtype=per_mask.dtype,
        device=per_mask.device,
    )
    return (per_mask * channel_weights).sum(1)


class SceneShape(torch.nn.Module):
    """The parameters both stages share: the object's size, the static cuboids' ground
    position, yaw and size, and the camera's height and elevation.

    Sizes and the height are kept unconstrained (:func:`positive_inverse`) above their floors
    (:data:`MIN_OBJECT_SIZE`, :data:`MIN_STATIC_SIZE`, :data:`MIN_CAMERA_HEIGHT`). A stage
    registers them with :meth:`register_shape` where they belong among its own parameters
    (their order and names are those of its checkpoints).
    """

    def register_shape(self, start: SceneTrajectories) -> None:
        """Register the shared parameters, started at ``start``'s values (on the CPU)."""
        P = torch.nn.Parameter
        self.object_size_raw = P(positive_inverse(start.object_size, MIN_OBJECT_SIZE))
        self.static_xy = P(start.static_pos[:, :2].clone())
        self.static_yaw = P(torch.atan2(start.static_rot[:, 1, 0], start.static_rot[:, 0, 0]))
        self.static_size_raw = P(positive_inverse(start.static_size, MIN_STATIC_SIZE))
        self.camera_height_raw = P(positive_inverse(start.camera_height, MIN_CAMERA_HEIGHT))
        self.camera_elevation = P(start.camera_elevation.clone())

    def free_sizes(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The object's size (3,), the static sizes (K, 3) and the camera height (0-d) [m], as
        the parameters give them (before a stage's scale or known lengths)."""
        return (positive(self.object_size_raw, MIN_OBJECT_SIZE), positive(self.static_size_raw, MIN_STATIC_SIZE),
                positive(self.camera_height_raw, MIN_CAMERA_HEIGHT))


def render_scene(scene: SceneTrajectories, intrinsics: Intrinsics, sigma: float) -> torch.Tensor:
    """Soft visible masks (N, 2 + K, h, w) of a per-frame scene: hand, object, statics."""
    cuboid_pos, cuboid_rot, cuboid_size = scene_cuboids(scene)
    return render_silhouettes(
        scene.hand_pos,
        scene.hand_rot,
        cuboid_pos,
        cuboid_rot,
        cuboid_size,
        scene.camera_height,
        scene.camera_elevation,
        intrinsics,
        sigma=sigma,
    )


def camera_height_prior(scene: SceneTrajectories, weights: LossWeights) -> torch.Tensor:
    """Weak prior on the scene's size: ``log(camera height / typical height)^2``, weighted.

    Masks fix the scale through one cue, the apparent width of the fixed-size hand; box
    annotations carry none, and neither do the hand's frames far from the camera. This
    term decides where the masks leave the scale open, and yields where they fix it.
    """
    return weights.camera_height * torch.log(scene.camera_height / weights.typical_camera_height).square()


def footprint_prior(scene: SceneTrajectories, weights: LossWeights) -> torch.Tensor:
    """Weak prior on the object's depth: ``log(depth / width)^2``, weighted (its own y and x sizes).

    Seen from the front, an object's depth shows only through its top face; a box around
    it shows none of it, and a deeper object farther away then draws the same box as the
    true one (with a known height, such objects come out too deep and their scenes too far).
    A footprint about as deep as wide decides where the view leaves the depth open;
    :meth:`~warpskill.optimizer.weights.LossWeights.for_scene` says where.
    """
    return weights.object_footprint * torch.log(scene.object_size[1] / scene.object_size[0]).square()


def noun_size_prior(scene: SceneTrajectories, weights: LossWeights,
                    typical_edges: tuple[float, float, float]) -> torch.Tensor:
    """Weak prior on the object's size from what it is: ``sum_i log(edge_i / typical_i)^2``
    over the edges sorted ascending, weighted, ``typical_edges`` [m] being those of its noun's
    typical size (:func:`warpskill.nouns.typical.typical_size`), in ascending order.

    Boxes leave the scale open (a larger scene farther away draws the same boxes), and the
    camera-height prior alone would decide it; and they show neither the object's depth nor
    how thin it is (a fork lying across its box fills the box). Sorted edges compare the
    object's extents whatever its axes: a fork comes out long and thin, a plate flat.
    :meth:`~warpskill.optimizer.weights.LossWeights.for_scene` says where it applies.
    """
    edges = torch.sort(scene.object_size).values
    typical = edges.new_tensor(typical_edges)
    return weights.object_noun_size * torch.log(edges / typical).square().sum()


def static_noun_size_prior(scene: SceneTrajectories, weights: LossWeights,
                           static_edges: Sequence[tuple[float, float, float] | None]) -> torch.Tensor:
    """:func:`noun_size_prior` for the static objects: ``sum_k sum_i log(edge_ki / typical_ki)^2``
    over the statics k whose ``static_edges`` [m] (their nouns' typical edges, ascending) are
    given, weighted by ``weights.static_noun_size``. A box shows neither a static's depth nor,
    where the frame cuts it, its hidden extent; its noun tells both (a book is flat, a tray wide)."""
    terms = [torch.log(torch.sort(scene.static_size[k]).values / scene.static_size.new_tensor(edges)).square().sum()
             for k, edges in enumerate(static_edges) if edges is not None]
    return weights.static_noun_size * torch.stack(terms).sum()


def scene_priors(
    scene: SceneTrajectories, weights: LossWeights, supported: torch.Tensor | None = None,
    behind: torch.Tensor | None = None, *, whole_object_behind: bool = False,
    typical_edges: tuple[float, float, float] | None = None,
    static_edges: Sequence[tuple[float, float, float] | None] = (),
) -> dict[str, torch.Tensor]:
    """The terms both stages add on the scene itself: the camera-height and footprint priors, the
    static boxes held out of the object and, where given, the placements "on the static" (``supported``,
    (N,)) and "behind the static" (``behind``, (N,); with ``whole_object_behind``, the
    object's front rather than its centre: see :func:`in_front_of_back_penalty`) and the size
    priors of the object's noun (``typical_edges`` [m]: see :func:`noun_size_prior`) and of the
    statics' (``static_edges``: see :func:`static_noun_size_prior`)."""
    terms = {
        "camera height": camera_height_prior(scene, weights),
        "object footprint": footprint_prior(scene, weights),
        "static in object": static_in_object_penalty(scene, weights),
    }
    if typical_edges is not None:
        terms["object noun size"] = noun_size_prior(scene, weights, typical_edges)
    if any(edges is not None for edges in static_edges) and weights.static_noun_size > 0:
        terms["static noun size"] = static_noun_size_prior(scene, weights, static_edges)
    if supported is not None:
        terms["on the static"] = off_static_penalty(scene, supported, weights)
    if behind is not None:
        terms["behind the static"] = in_front_of_back_penalty(scene, behind, weights, whole_object_behind)
    return terms


def off_static_penalty(scene: SceneTrajectories, supported: torch.Tensor, weights: LossWeights) -> torch.Tensor:
    """How far the object's centre lies outside the first static box's footprint, shrunk by a
    margin, in the ``supported`` (N,) frames (squared [m^2], weighted): the placement "on the static".

    The margin, half the smaller of the object's half width and the static's half side, keeps
    the centre off the edge: a centre just inside the top face tips over in the physics
    and the object falls off the box it was put on."""
    local = (scene.object_pos - scene.static_pos[0]) @ scene.static_rot[0]
    half = 0.5 * scene.static_size[0, :2]
    margin = 0.5 * torch.minimum(0.5 * scene.object_size[:2].min(), half)
    outside = (local[:, :2].abs() - (half - margin)).clamp_min(0.0).square().sum(-1)
    return weights.penetration * (supported.to(outside) * outside).mean()


def in_front_of_back_penalty(
    scene: SceneTrajectories, behind: torch.Tensor, weights: LossWeights, whole_object: bool = False
) -> torch.Tensor:
    """How far the object lies in front of the first static box's back [m, squared, weighted]
    in the ``behind`` (N,) frames: where the static box hides the object's lower part, the
    object stands behind it (the camera looks along +y).

    Measured at the object's centre, or with ``whole_object`` at its front: the physics
    stage asks for the whole object past the back, because a released object whose front
    is still over the box lands on the box's edge; the per-frame fit, which has no
    physics, asks only for its centre.
    """
    half_depth = 0.5 * (scene.object_rot[:, 1, :].abs() * scene.object_size).sum(-1) if whole_object else 0.0
    short = (static_back(scene) - (scene.object_pos[:, 1] - half_depth)).clamp_min(0.0).square()
    return weights.penetration * (behind.to(short) * short).mean()


def ends_behind_static(scene: SceneTrajectories) -> bool:
    """Whether the object's last centre lies behind the first static box's back (farther from the camera)."""
    return bool(scene.object_pos[-1, 1] > static_back(scene))


def final_bottom(scene: SceneTrajectories) -> float:
    """Height [m] of the object's lowest point in the last frame."""
    rot, size = scene.object_rot[-1], scene.object_size
    return float(scene.object_pos[-1, 2] - 0.5 * (rot[2].abs() * size).sum())


def static_back(scene: SceneTrajectories) -> torch.Tensor:
    """The depth y [m] (0-d) of the first static box's back, the face farthest from the camera."""
    yaw_cos, yaw_sin = scene.static_rot[0, 0, 0].abs(), scene.static_rot[0, 1, 0].abs()
    return scene.static_pos[0, 1] + 0.5 * (yaw_cos * scene.static_size[0, 1] + yaw_sin * scene.static_size[0, 0])


_TOP_GRID = torch.tensor([[x, y, 0.5] for x in (-0.5, 0.0, 0.5) for y in (-0.5, 0.0, 0.5)])  # (9, 3) of a unit box


def static_in_object_penalty(scene: SceneTrajectories, weights: LossWeights) -> torch.Tensor:
    """How deep the static boxes' top faces reach into the object from below (squared [m^2], weighted).

    The engine samples points on the moved object only, so a static box smaller than the
    object can sit inside it with every sample point's push cancelling another's; the 3 x 3
    grid of each static top face is held out of the object here. The object counts as
    reaching up without end (its top face does not push), so the way out is up or sideways,
    as for an object lowered onto a box, never down through the ground.
    """
    if scene.static_pos.shape[0] == 0:
        return scene.object_size.new_zeros(())
    grid = _TOP_GRID.to(scene.static_size)
    points = scene.static_pos[:, None] + (grid * scene.static_size[:, None]) @ scene.static_rot.transpose(-1, -2)
    points = points.reshape(1, -1, 3)  # (1, 9 K, 3)
    local = (points - scene.object_pos[:, None]) @ scene.object_rot  # (N, 9 K, 3) in the object's frame
    half = 0.5 * scene.object_size
    excess = torch.stack([local[..., 0].abs() - half[0], local[..., 1].abs() - half[1], -local[..., 2] - half[2]], -1)
    depth = (-excess.amax(-1)).clamp_min(0.0)
    return weights.penetration * depth.square().sum(-1).mean()
