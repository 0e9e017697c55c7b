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
from warpskill.engine.projection import camera_rotation
from warpskill.engine.rendering import render_silhouettes
from warpskill.engine.simulation import Rollout
from warpskill.engine.simulation import simulate as warp_simulate
from warpskill.optimizer.scene import SceneTrajectories


@dataclass(frozen=True)
class Backend:
    """The engine under the optimiser: a rollout and a rasterizer with the signatures of
    :func:`warpskill.engine.simulation.simulate` and :func:`warpskill.engine.rendering.render_silhouettes`.

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
    N, K = scene.hand_pos.shape[0], scene.static_pos.shape[0]
    dtype = scene.hand_pos.dtype
    zero = scene.camera_elevation.new_zeros(())
    Q = (camera_rotation(zero) @ camera_rotation(scene.camera_elevation).transpose(-1, -2)).to(dtype)
    centre = torch.stack([zero, zero, scene.camera_height]).to(dtype)
    move = lambda p: (p - centre) @ Q.T  # noqa: E731
    cuboid_pos = torch.cat([scene.object_pos[:, None], scene.static_pos[None].expand(N, K, 3)], dim=1)
    cuboid_rot = torch.cat([scene.object_rot[:, None], scene.static_rot[None].expand(N, K, 3, 3)], dim=1)
    cuboid_size = torch.cat([scene.object_size[None], scene.static_size], dim=0)
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


def simulate_many(inputs: Sequence[dict], simulate: Callable = warp_simulate):
    """Roll out each scene's :meth:`~warpskill.optimizer.stage_b.PhysicalScene.simulation_inputs`,
    one engine call per group; returns each scene's :class:`~warpskill.engine.simulation.Rollout` (B = 1)
    over its own frames."""
    keys = [(x["steps_per_frame"], x["fps"], x["static_pos"].shape[1], x["config"]) for x in inputs]
    out: list[Rollout | None] = [None] * len(inputs)
    for members in groups(keys):
        steps = [inputs[i]["hand_vel"].shape[1] for i in members]
        longest = max(steps)
        batch = {
            name: torch.cat([
                torch.nn.functional.pad(inputs[i][name], (0, 0, 0, longest - n)) if name == "hand_vel"
                else inputs[i][name]
                for i, n in zip(members, steps)
            ])
            for name, value in inputs[members[0]].items()
            if torch.is_tensor(value)
        }
        options = {name: value for name, value in inputs[members[0]].items() if not torch.is_tensor(value)}
        rollout = simulate(**batch, **options)
        spf = options["steps_per_frame"]
        for b, (i, n) in enumerate(zip(members, steps)):
            frames = n // spf + 1
            out[i] = Rollout(**{name: value[b : b + 1, :frames] for name, value in vars(rollout).items()})
    return out
