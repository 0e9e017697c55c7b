"""Many scenes through one engine call: the rollouts and the silhouettes of a batch.

:func:`warpskill.optimize_many` optimises several scenes (demonstrations, or hypotheses
of one) side by side; each iteration simulates all of them in one rollout and renders all
their frames in one raster launch, grouped by what one call must share:

- rollouts: the frame rate, substeps and number of static cuboids; shorter scenes are
  padded with still hand velocities at the end (their own frames are unaffected);
- silhouettes: the intrinsics, working image size and number of static cuboids; in a group
  of several, each scene's poses are moved rigidly into its own camera frame first, so one
  shared camera renders them all and the gradients still reach every scene's camera height
  and elevation (a group of one is drawn with its own camera).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import Callable, Hashable, Sequence

import torch

from warpskill.contract.camera import Intrinsics
from warpskill.engine.primitives import scene_cuboids
from warpskill.engine.projection import camera_rotation
from warpskill.engine.records import Rollout, SceneInputs
from warpskill.engine.rendering import render_silhouettes, silhouette_profiles
from warpskill.engine.simulation import simulate as warp_simulate
from warpskill.optimizer.losses import MaskProfile, MaskTargets
from warpskill.optimizer.scene import SceneTrajectories


@dataclass(frozen=True)
class Backend:
    """The engine under the optimiser: a rollout and a rasterizer with the signatures of
    :func:`warpskill.engine.simulation.simulate` (a :class:`~warpskill.engine.records.SceneInputs`
    and the keyword options) and :func:`warpskill.engine.rendering.render_silhouettes`, and
    the rasterizer's mask profiles (:func:`warpskill.engine.rendering.silhouette_profiles`),
    or None to take them from its masks.

    ``warpskill bench speed`` swaps in the plain-Torch references through this.
    """

    name: str = "warp"
    simulate: Callable = warp_simulate
    render: Callable = render_silhouettes
    profile: Callable | None = silhouette_profiles


def groups(keys: Sequence[Hashable]) -> list[list[int]]:
    """Indices of equal keys, in order of first appearance."""
    by_key: dict[Hashable, list[int]] = defaultdict(list)
    for i, key in enumerate(keys):
        by_key[key].append(i)
    return list(by_key.values())


def in_camera_frame(scene: SceneTrajectories) -> tuple[torch.Tensor, ...]:
    """The scene's hand and cuboid poses moved rigidly so that a camera at height 0 and
    elevation 0 sees them as the scene's own camera does.

    Returns:
        hand_pos (N, 3), hand_rot (N, 3, 3), cuboid_pos (N, 1 + K, 3), cuboid_rot (N, 1 + K, 3, 3),
        cuboid_size (1 + K, 3): the object first, then the statics.
    """
    dtype = scene.hand_pos.dtype
    zero = scene.camera_elevation.new_zeros(())
    Q = (camera_rotation(zero) @ camera_rotation(scene.camera_elevation).transpose(-1, -2)).to(dtype)
    centre = torch.stack([zero, zero, scene.camera_height]).to(dtype)
    move = lambda p: (p - centre) @ Q.T  # noqa: E731
    cuboid_pos, cuboid_rot, cuboid_size = scene_cuboids(scene)
    return move(scene.hand_pos), Q @ scene.hand_rot, move(cuboid_pos), Q @ cuboid_rot, cuboid_size


def render_many(
    scenes: Sequence[SceneTrajectories], intrinsics: Sequence[Intrinsics], sigma: float,
    backend: Backend = Backend(), targets: Sequence[MaskTargets] | None = None,
) -> list[torch.Tensor] | list[MaskProfile]:
    """Soft visible masks (N_i, 2 + K_i, h_i, w_i) of each scene, or with ``targets`` their
    :class:`~warpskill.optimizer.losses.MaskProfile` against each scene's targets (without
    forming the masks where the backend can), one raster call per group.

    Args:
        scenes: per-frame scenes (each with its own camera).
        intrinsics: each scene's working-resolution intrinsics.
        sigma: soft edge width [px].
        backend: the rasterizer (:attr:`Backend.render`, :attr:`Backend.profile`).
        targets: each scene's target masks (scenes may share them).
    """
    keys = [(intr.K.tobytes(), tuple(intr.image_size), scene.static_pos.shape[0], scene.hand_pos.dtype)
            for scene, intr in zip(scenes, intrinsics)]
    out: list = [None] * len(scenes)
    for members in groups(keys):
        frames = [scenes[i].hand_pos.shape[0] for i in members]
        poses = (*_group_poses([scenes[i] for i in members]), intrinsics[members[0]])
        if targets is not None and backend.profile is not None:
            stacked, frame_index = _stacked_targets([targets[i] for i in members])
            profiles = backend.profile(*poses, stacked, frame_index, sigma=sigma)
            parts = [MaskProfile(*profile) for profile in zip(*(p.split(frames) for p in profiles))]
        else:
            parts = backend.render(*poses, sigma=sigma).split(frames)
            if targets is not None:
                parts = [MaskProfile.of(masks, targets[i]) for i, masks in zip(members, parts)]
        for i, part in zip(members, parts):
            out[i] = part
    return out


def _group_poses(scenes: Sequence[SceneTrajectories]) -> tuple[torch.Tensor, ...]:
    """The raster's scene arguments for a group: hand_pos, hand_rot, cuboid_pos, cuboid_rot,
    cuboid_size per frame (sum N_i, ...), camera height and elevation. One scene is drawn with
    its own camera; several are each moved into their camera's frame (:func:`in_camera_frame`)
    and drawn with a camera at height 0 and elevation 0."""
    if len(scenes) == 1:
        scene = scenes[0]
        return (scene.hand_pos, scene.hand_rot, *scene_cuboids(scene), scene.camera_height, scene.camera_elevation)
    moved = [in_camera_frame(scene) for scene in scenes]
    zero = scenes[0].camera_height.new_zeros(())
    return (
        torch.cat([m[0] for m in moved]),
        torch.cat([m[1] for m in moved]),
        torch.cat([m[2] for m in moved]),
        torch.cat([m[3] for m in moved]),
        torch.cat([m[4][None].expand(len(m[0]), -1, 3) for m in moved]),
        zero,
        zero,
    )


def _stacked_targets(targets: Sequence[MaskTargets]) -> tuple[torch.Tensor, torch.Tensor]:
    """The distinct target masks of a group (T, C, h, w), stacked (copied only where there are
    several), and each of the group's frames' index into them (sum N_i,)."""
    distinct: dict[int, int] = {}  # id -> first row in the stack
    stack, index, rows = [], [], 0
    for target in targets:
        if id(target) not in distinct:
            distinct[id(target)] = rows
            stack.append(target.masks)
            rows += len(target.masks)
        first = distinct[id(target)]
        index.append(torch.arange(first, first + len(target.masks), device=target.masks.device))
    return (stack[0] if len(stack) == 1 else torch.cat(stack)), torch.cat(index)


def simulate_many(
    inputs: Sequence[SceneInputs], options: Sequence[dict], simulate: Callable = warp_simulate
) -> list[Rollout]:
    """Roll out scenes (B = 1 each), one engine call per group of equal options and K.

    Args:
        inputs: each scene's :meth:`~warpskill.optimizer.stage_b.PhysicalScene.simulation_inputs`.
        options: each scene's keyword arguments of ``simulate`` (``steps_per_frame``, ``fps``,
            ``config``: :meth:`~warpskill.optimizer.stage_b.PhysicalScene.simulation_options`).
        simulate: the rollout (:attr:`Backend.simulate`).

    Returns:
        Each scene's :class:`~warpskill.engine.records.Rollout` (B = 1) over its own frames.
    """
    keys = [(tuple(sorted(o.items())), x.static_pos.shape[1]) for x, o in zip(inputs, options)]
    out: list[Rollout | None] = [None] * len(inputs)
    for members in groups(keys):
        steps = [inputs[i].hand_vel.shape[1] for i in members]
        group_options = options[members[0]]
        rollout = simulate(SceneInputs.cat([inputs[i] for i in members]), **group_options)
        spf = group_options["steps_per_frame"]
        for b, (i, n) in enumerate(zip(members, steps)):
            frames = n // spf + 1
            out[i] = rollout.map(lambda value: value[b : b + 1, :frames])
    return out
