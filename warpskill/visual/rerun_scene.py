"""What a Rerun recording shows, checked and computed once: label images, video frames, the robot.

:func:`prepare_scene` checks the inputs of :func:`warpskill.visual.rerun_view.view` against
each other and computes the demonstration's and the reconstruction's label images. The
robot comes as a track already posed (:func:`warpskill.robot.robot_track`; visual never
imports the robot). It imports no Rerun: :mod:`.rerun_entities` logs the result.
"""

from __future__ import annotations

import dataclasses
import functools
import types

import numpy as np
import torch

from warpskill.contract.camera import Intrinsics
from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.replay import Replay
from warpskill.engine.rendering import render_silhouettes

__all__ = ["CLASS_IDS", "ROBOT_TRACK_FIELDS", "SceneData", "mask_labels", "prepare_scene", "rendered_labels"]

CLASS_IDS = {"background": 0, "hand": 1, "object": 2, "static": 3}
"""Class ids of the label images: static object k has id ``3 + k``."""

LABEL_THRESHOLD = 0.5
"""Soft silhouette coverage above which a rendered pixel counts as covered."""


ROBOT_TRACK_FIELDS = ("times", "links", "shapes", "gripper", "base", "simulated")
"""What a robot track has (:class:`warpskill.robot.RobotTrack`): (F,) times [s], link name ->
(F, 4, 4) world poses, link name -> collision shapes (``kind``, ``pose``, ``size``,
``vertices``, ``triangles``), (F,) gripper opening [m], (4, 4) base pose, and whether the
joints are simulated."""


@dataclasses.dataclass
class SceneData:
    """Everything a recording logs (computed once, also reused when serving).

    Attributes:
        recon: the reconstruction.
        demo: its demonstration, or None.
        frames: (N, H, W, 3) uint8 RGB video frames of the demonstration, or None.
        masks: (N, H, W) uint8 class ids of the demonstration's masks, or None.
        rendered: (N, H, W) uint8 class ids the reconstruction's camera sees.
        replayed: the replay's reconstruction (gripper TCP and simulated object), or None.
        robot: the Panda's track (:data:`ROBOT_TRACK_FIELDS`), or None.
    """

    recon: Reconstruction
    demo: Demonstration | None
    frames: np.ndarray | None
    masks: np.ndarray | None
    rendered: np.ndarray
    replayed: Reconstruction | None
    robot: object | None


def prepare_scene(
    recon: Reconstruction,
    demo: Demonstration | None = None,
    robot=None,
    replay: Replay | None = None,
    frames: np.ndarray | None = None,
) -> SceneData:
    """Check the inputs against each other; compute the label images.

    Raises:
        TypeError: an argument of the wrong type.
        ValueError: ``demo``, ``replay`` or ``frames`` disagree with ``recon`` (frame count,
            image size, intrinsics, frame rate).
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
    if robot is not None and not all(hasattr(robot, name) for name in ROBOT_TRACK_FIELDS):
        raise TypeError(f"robot: expected a robot track (warpskill.robot.robot_track(plan, fps, replay)), "
                        f"got {type(robot).__name__}")
    return SceneData(
        recon=recon,
        demo=demo,
        frames=None if frames is None else _checked_frames(recon, frames),
        masks=None if demo is None else mask_labels(demo),
        rendered=rendered_labels(recon),
        replayed=replayed,
        robot=robot,
    )


def _checked_frames(recon: Reconstruction, frames: np.ndarray) -> np.ndarray:
    """``frames`` as (N, H, W, 3) uint8 of the reconstruction's N frames and image size."""
    frames = np.asarray(frames)
    expected = (recon.num_frames, *(int(x) for x in recon.image_size), 3)
    if frames.shape != expected or frames.dtype != np.uint8:
        raise ValueError(f"frames: expected {expected} uint8 RGB frames of the reconstruction, "
                         f"got {frames.shape} {frames.dtype}")
    return frames


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
