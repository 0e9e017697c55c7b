"""The Panda's links at the frames of a reconstruction, for the 3D recording to draw.

:func:`robot_track` samples a plan (or its replay's simulated joints) at the
reconstruction's frame rate and poses the links by :func:`~warpskill.robot.link_poses`.
The result is plain arrays, so :mod:`warpskill.visual` draws it without importing the
robot (the command line hands it over).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from warpskill.contract.replay import Replay
from warpskill.robot.kinematics import LinkShape, link_poses, link_shapes
from warpskill.robot.plan import RobotPlan

__all__ = ["RobotTrack", "robot_track"]


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


def robot_track(plan: RobotPlan, fps: float, replay: Replay | None = None) -> RobotTrack:
    """The Panda at the frames :func:`warpskill.robot.replay` samples: plan time ``start_time + k / fps``.

    Args:
        plan: the robot plan.
        fps: the reconstruction's frame rate [1/s].
        replay: the plan's replay: the arm follows its simulated joints; None: the plan's
            (interpolated at the frames).

    Raises:
        TypeError: ``plan`` is not a :class:`RobotPlan` or ``replay`` not a :class:`Replay`.
        ValueError: ``replay`` has another number of frames than the plan samples at ``fps``.
        ModuleNotFoundError: MuJoCo is not installed.
        RuntimeError: the Panda model (``example-robot-data``) is not installed.
    """
    if not isinstance(plan, RobotPlan):
        raise TypeError(f"plan: expected a warpskill.RobotPlan, got {type(plan).__name__}")
    if replay is not None and not isinstance(replay, Replay):
        raise TypeError(f"replay: expected a warpskill.Replay or None, got {type(replay).__name__}")
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
