"""What a Rerun recording shows, checked and computed once: label images and the robot's track.

:func:`prepare_scene` checks the inputs of :func:`warpskill.visual.rerun_view.view` against
each other and computes the demonstration's and the reconstruction's label images and the
Panda's link poses (:func:`warpskill.robot.link_poses`) at the replay's frames. It imports
no Rerun: :mod:`.rerun_entities` logs the result.
"""

from __future__ import annotations

import dataclasses
import functools
import types
from typing import TYPE_CHECKING

import numpy as np

from warpskill.contract.camera import Intrinsics
from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.replay import Replay

if TYPE_CHECKING:
    from warpskill.robot.kinematics import LinkShape
    from warpskill.robot.plan import RobotPlan

__all__ = ["CLASS_IDS", "RobotTrack", "SceneData", "mask_labels", "prepare_scene", "rendered_labels", "robot_track"]

CLASS_IDS = {"background": 0, "hand": 1, "object": 2, "static": 3}
"""Class ids of the label images: static object k has id ``3 + k``."""

LABEL_THRESHOLD = 0.5
"""Soft silhouette coverage above which a rendered pixel counts as covered."""


@dataclasses.dataclass
class RobotTrack:
    """The Panda at F frames, frame k at recording time k / fps.

    Attributes:
        times: (F,) recording time [s] of each frame.
        links: link name -> (F, 4, 4) world poses (:func:`warpskill.robot.link_poses`).
        shapes: link name -> its collision shapes in the link frame (:func:`warpskill.robot.link_shapes`).
        gripper: (F,) commanded gripper opening [m] (the plan's, at the frames).
        base: (4, 4) world pose of the robot base.
        simulated: whether the arm joints are the replay's (True) or the plan's (False).
    """

    times: np.ndarray
    links: dict[str, np.ndarray]
    shapes: dict[str, list[LinkShape]]
    gripper: np.ndarray
    base: np.ndarray
    simulated: bool


@dataclasses.dataclass
class SceneData:
    """Everything a recording logs (computed once, also reused when serving).

    Attributes:
        recon: the reconstruction.
        demo: its demonstration, or None.
        masks: (N, H, W) uint8 class ids of the demonstration's masks, or None.
        rendered: (N, H, W) uint8 class ids the reconstruction's camera sees.
        replayed: the replay's reconstruction (gripper TCP and simulated object), or None.
        robot: the Panda's track, or None.
    """

    recon: Reconstruction
    demo: Demonstration | None
    masks: np.ndarray | None
    rendered: np.ndarray
    replayed: Reconstruction | None
    robot: RobotTrack | None


def prepare_scene(
    recon: Reconstruction,
    demo: Demonstration | None = None,
    plan: RobotPlan | None = None,
    replay: Replay | None = None,
) -> SceneData:
    """Check the inputs against each other; compute the label images and the robot's track.

    Raises:
        TypeError: an argument of the wrong type.
        ValueError: ``demo`` or ``replay`` disagrees with ``recon`` (frame count, image
            size, intrinsics, frame rate), or ``replay`` with ``plan`` (frame count).
    """
    if not isinstance(recon, Reconstruction):
        raise TypeError(f"recon: expected a warpskill.Reconstruction, got {type(recon).__name__}")
    if demo is not None:
        _check_demo(recon, demo)
    replayed = None
    if replay is not None:
        if not isinstance(replay, Replay):
            raise TypeError(f"replay: expected a warpskill.Replay or None, got {type(replay).__name__}")
        replayed = replay.reconstruction
        if not np.isclose(float(replayed.fps), float(recon.fps)):
            raise ValueError(f"replay fps {float(replayed.fps)} differs from the reconstruction's {float(recon.fps)}")
        if np.shape(replay.joints) != (replayed.num_frames, 7):
            raise ValueError(f"replay.joints: expected shape ({replayed.num_frames}, 7), got {np.shape(replay.joints)}")
    robot = None
    if plan is not None:
        from warpskill.robot.plan import RobotPlan

        if not isinstance(plan, RobotPlan):
            raise TypeError(f"plan: expected a warpskill.RobotPlan or None, got {type(plan).__name__}")
        robot = robot_track(plan, float(recon.fps), replay)
    return SceneData(
        recon=recon,
        demo=demo,
        masks=None if demo is None else mask_labels(demo),
        rendered=rendered_labels(recon),
        replayed=replayed,
        robot=robot,
    )


def _check_demo(recon: Reconstruction, demo: Demonstration) -> None:
    if not isinstance(demo, Demonstration):
        raise TypeError(f"demo: expected a warpskill.Demonstration or None, got {type(demo).__name__}")
    N = recon.num_frames
    size = tuple(int(x) for x in recon.image_size)
    if demo.num_frames != N:
        raise ValueError(f"demo has {demo.num_frames} frames, the reconstruction {N}")
    if tuple(demo.image_size) != size:
        raise ValueError(f"demo images are {tuple(demo.image_size)} (H, W), the reconstruction's {size}")
    if not np.isclose(float(demo.fps), float(recon.fps)):
        raise ValueError(f"demo fps {float(demo.fps)} differs from the reconstruction's {float(recon.fps)}")
    if not np.allclose(demo.intrinsics.K, recon.camera_K, rtol=1e-6, atol=1e-6):
        raise ValueError(
            f"demo camera_K {demo.intrinsics.K.tolist()} differs from the reconstruction's {recon.camera_K.tolist()}"
        )


def mask_labels(demo: Demonstration) -> np.ndarray:
    """(N, H, W) uint8 class ids (:data:`CLASS_IDS`) of the demonstration's masks (static under hand under object)."""
    labels = np.zeros(demo.hand_mask.shape, np.uint8)
    for k, mask in enumerate(demo.static_mask):
        labels[mask] = CLASS_IDS["static"] + k
    labels[demo.hand_mask] = CLASS_IDS["hand"]
    labels[demo.object_mask] = CLASS_IDS["object"]
    return labels


_RENDERED_FIELDS = ("hand_pos", "hand_rot", "object_pos", "object_rot", "object_size", "static_pos", "static_rot",
                    "static_size", "camera_K", "camera_height", "camera_elevation", "image_size")


def rendered_labels(recon: Reconstruction) -> np.ndarray:
    """What the reconstruction's camera sees, by :func:`warpskill.render_silhouettes`.

    A pixel gets the class of the primitive with the largest soft coverage, if that exceeds
    :data:`LABEL_THRESHOLD` (the silhouettes are occlusion-aware: each pixel belongs to the
    nearest primitive). The last result is kept, keyed by the values of the fields drawn:
    ``warpskill demo`` records the same reconstruction again with the robot.

    Returns:
        (N, H, W) uint8 class ids (:data:`CLASS_IDS`), read-only: 0 nothing, 1 the hand,
        2 the object, 3 + k static object k.
    """
    arrays = {name: np.asarray(getattr(recon, name), dtype=float) for name in _RENDERED_FIELDS}
    return _render_once(tuple((name, a.shape, a.tobytes()) for name, a in arrays.items()))


@functools.lru_cache(maxsize=1)
def _render_once(key: tuple) -> np.ndarray:
    """:func:`rendered_labels` of the fields ``key``: (name, shape, float64 bytes) each."""
    labels = _render(types.SimpleNamespace(**{name: np.frombuffer(data).reshape(shape).copy() for name, shape, data in key}))
    labels.flags.writeable = False
    return labels


def _render(recon) -> np.ndarray:
    import torch

    from warpskill.engine.rendering import render_silhouettes

    H, W = (int(x) for x in recon.image_size)
    N, K = len(recon.hand_pos), len(recon.static_pos)
    cuboid_pos = np.concatenate([recon.object_pos[:, None], np.broadcast_to(recon.static_pos, (N, K, 3))], axis=1)
    cuboid_rot = np.concatenate([recon.object_rot[:, None], np.broadcast_to(recon.static_rot, (N, K, 3, 3))], axis=1)
    cuboid_size = np.concatenate([recon.object_size[None], recon.static_size], axis=0)

    def tensor(x):
        return torch.tensor(np.asarray(x), dtype=torch.float32)

    with torch.no_grad():
        masks = render_silhouettes(
            tensor(recon.hand_pos),
            tensor(recon.hand_rot),
            tensor(cuboid_pos),
            tensor(cuboid_rot),
            tensor(cuboid_size),
            tensor(recon.camera_height),
            tensor(recon.camera_elevation),
            Intrinsics(np.asarray(recon.camera_K, float), (H, W)),
        ).numpy()  # (N, 2 + K, H, W)
    # The channel of largest coverage above the threshold (a loop over the few channels: a
    # strided argmax over axis 1 is several times slower).
    labels = np.zeros(masks[:, 0].shape, np.uint8)
    best = np.full(masks[:, 0].shape, LABEL_THRESHOLD, masks.dtype)
    for channel in range(masks.shape[1]):
        better = masks[:, channel] > best
        labels[better] = channel + 1
        np.maximum(best, masks[:, channel], out=best)
    return labels


def robot_track(plan: RobotPlan, fps: float, replay: Replay | None = None) -> RobotTrack:
    """The Panda at the frames :func:`warpskill.robot.replay` samples: plan time ``start_time + k / fps``.

    Args:
        plan: the robot plan.
        fps: the reconstruction's frame rate.
        replay: the plan's replay: the arm follows its simulated joints; None: the plan's
            (interpolated at the frames).

    Raises:
        ValueError: ``replay`` has another number of frames than the plan samples at ``fps``.
        ModuleNotFoundError: MuJoCo is not installed.
        RuntimeError: the Panda model (``example-robot-data``) is not installed.
    """
    from warpskill.robot.kinematics import link_poses, link_shapes

    count = len(np.arange(plan.start_time, plan.t[-1] + 1e-9, 1.0 / fps))
    plan_times = plan.start_time + np.arange(count) / fps
    if replay is None:
        joints = np.stack([np.interp(plan_times, plan.t, plan.q[:, i]) for i in range(7)], axis=1)
    elif len(replay.joints) != count:
        raise ValueError(f"replay has {len(replay.joints)} frames, the plan {count} at {fps:g} fps: not its replay")
    else:
        joints = np.asarray(replay.joints, float)
    gripper = np.interp(plan_times, plan.t, plan.gripper)
    base = np.asarray(plan.base, float)
    return RobotTrack(
        times=np.arange(count) / fps,
        links=link_poses(joints, gripper, base),
        shapes=link_shapes(),
        gripper=gripper,
        base=base,
        simulated=replay is not None,
    )
