"""Many scenes through one engine call: the rollouts and the silhouettes of a batch.

:func:`warpskill.optimize_many` optimises several scenes (demonstrations, or hypotheses
of one) side by side; each iteration simulates all of them in one rollout and renders all
their frames in one raster launch, grouped by what one call must share:

- rollouts: the frame rate, substeps and number of static cuboids; shorter scenes are
  padded with still hand velocities at the end (their own frames are unaffected);
- silhouettes: the intrinsics, working image size and number of static cuboids; each
  scene's poses are moved rigidly into its own camera frame first, so one shared camera
  renders them all and the gradients still reach every scene's camera height and elevation.
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
from warpskill.engine.rendering import render_silhouettes
from warpskill.engine.simulation import simulate as warp_simulate
from warpskill.optimizer.scene import SceneTrajectories


@dataclass(frozen=True)
class Backend:
    """The engine under the optimiser: a rollout and a rasterizer with the signatures of
    :func:`warpskill.engine.simulation.simulate` (a :class:`~warpskill.engine.records.SceneInputs`
    and the keyword options) and :func:`warpskill.engine.rendering.render_silhouettes`.

    ``warpskill bench speed`` swaps in the plain-Torch references through this.
    """

    name: str = "warp"
    simulate: Callable = warp_simulate
    render: Callable = render_silhouettes


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
    render: Callable = render_silhouettes,
) -> list[torch.Tensor]:
    """Soft visible masks (N_i, 2 + K_i, h_i, w_i) of each scene, one raster call per group.

    Args:
        scenes: per-frame scenes (each with its own camera).
        intrinsics: each scene's working-resolution intrinsics.
        sigma: soft edge width [px].
        render: the rasterizer (:attr:`Backend.render`).
    """
    keys = [(intr.K.tobytes(), tuple(intr.image_size), scene.static_pos.shape[0], scene.hand_pos.dtype)
            for scene, intr in zip(scenes, intrinsics)]
    out: list[torch.Tensor | None] = [None] * len(scenes)
    for members in groups(keys):
        moved = [in_camera_frame(scenes[i]) for i in members]
        frames = [m[0].shape[0] for m in moved]
        zero = scenes[members[0]].camera_height.new_zeros(())
        masks = render(
            torch.cat([m[0] for m in moved]),
            torch.cat([m[1] for m in moved]),
            torch.cat([m[2] for m in moved]),
            torch.cat([m[3] for m in moved]),
            torch.cat([m[4][None].expand(n, -1, 3) for m, n in zip(moved, frames)]),
            zero,
            zero,
            intrinsics[members[0]],
            sigma=sigma,
        )
        for i, part in zip(members, masks.split(frames)):
            out[i] = part
    return out


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
