"""Successful rollouts of a skill in random layouts, filmed by fixed cameras for a dataset.

For each layout of :func:`~warpskill.export.layouts.layouts`: the Panda's plan
(:func:`warpskill.robot.retarget`), its MuJoCo replay judged by the action's criteria
(:func:`warpskill.robot.replay`), and, where it succeeds (or on request where it fails), the same
run once more sampled at the dataset's rate from the plan's start (home) to its end, with every
camera rendered offscreen and the tool centre point recorded (:class:`Episode`). The physics is
deterministic, so the filmed run is the judged one. A refused layout or a failed replay is an
:class:`Attempt` with its reason, never an error.

The cameras (:data:`CAMERAS`) are fixed relative to the robot base, as cameras mounted on
its table: ``front`` looks at the workspace from the robot's front left (the replay video's
view), ``top`` from above; :meth:`Camera.calibration` gives each one's intrinsics and its pose in
the robot base frame.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator

import numpy as np

from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.skill import Layout, Skill
from warpskill.export.layouts import layouts
from warpskill.robot import replay, replay_mujoco, retarget
from warpskill.robot.model import FINGER_JOINTS
from warpskill.robot.plan import RobotPlan
from warpskill.robot.scene_config import load_scene_config
from warpskill.robot.skill_layout import apply_skill

__all__ = ["CAMERAS", "EE_POSE_NAMES", "ENGINE", "FOVY", "STATE_NAMES", "TASKS", "Attempt", "Calibration", "Camera",
           "Episode", "attempt", "film", "film_attempt", "pose_vectors", "rollouts"]

TASKS: dict[str, str] = {
    "pull_left_to_right": "pull the object from left to right",
    "pull_right_to_left": "pull the object from right to left",
    "push_left_to_right": "push the object from left to right",
    "push_right_to_left": "push the object from right to left",
    "pick_up": "pick up the object",
    "put_behind": "put the object behind the box",
    "put_in_front_of": "put the object in front of the box",
    "put_next_to": "put the object next to the box",
    "put_onto": "put the object onto the box",
}
"""The task text of each action, as the dataset states it."""

STATE_NAMES = [f"panda_joint{i}" for i in range(1, 8)] + ["gripper_opening"]
"""``observation.state``: the simulated arm joints [rad] and finger distance [m]; ``action``: the commanded ones."""

EE_POSE_NAMES = ["x", "y", "z", "qw", "qx", "qy", "qz"]
"""``observation.ee_pose``: the tool centre point in the robot base frame, position [m] and quaternion (w first)."""

ENGINE = "mujoco"
"""The engine that judges and films every rollout."""


FOVY = 45.0
"""[deg] vertical field of view of every dataset camera (MuJoCo's free camera, ``model.vis.global_.fovy``)."""


@dataclasses.dataclass(frozen=True)
class Calibration:
    """A dataset camera's pinhole model and its pose on the robot's table.

    Attributes:
        fx, fy, cx, cy: [px] focal lengths and principal point (OpenCV: pixel (0, 0) is the
            centre of the top-left pixel, x right, y down).
        width, height: [px] the frames' size.
        base_from_camera: (4, 4) the camera's pose in the robot base frame (x forward, z up,
            metres): maps camera coordinates (OpenCV axes: x right, y down, z along the view) to the base's.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    base_from_camera: np.ndarray

    def to_json(self) -> dict:
        """The record as JSON-ready numbers (the pose as 4 rows of 4)."""
        fields = dataclasses.asdict(self)
        fields["base_from_camera"] = np.round(self.base_from_camera, 9).tolist()
        return fields


@dataclasses.dataclass(frozen=True)
class Camera:
    """A MuJoCo free camera fixed relative to the robot base.

    Attributes:
        name: the feature is ``observation.images.<name>``.
        ahead: [m] the point looked at lies this far ahead of the base (base +x) ...
        height: [m] ... and this high above the table.
        distance: [m] from that point.
        azimuth: [deg] of the viewing direction about z, from the base's forward axis.
        elevation: [deg] of the viewing direction (negative: looking down).
    """

    name: str
    ahead: float
    height: float
    distance: float
    azimuth: float
    elevation: float

    def view(self, base: np.ndarray):
        """The ``mujoco.MjvCamera`` of this camera for a robot at ``base`` (4, 4)."""
        import mujoco  # optional extra: robot (imported after prefer_headless_gl picks its GL)

        camera = mujoco.MjvCamera()
        camera.lookat[:] = base[:3, :3] @ np.array([self.ahead, 0.0, 0.0]) + base[:3, 3] + [0.0, 0.0, self.height]
        camera.distance = self.distance
        camera.azimuth = math.degrees(math.atan2(base[1, 0], base[0, 0])) + self.azimuth
        camera.elevation = self.elevation
        return camera

    def base_from_camera(self) -> np.ndarray:
        """(4, 4) the camera's pose in the robot base frame, OpenCV axes (see :class:`Calibration`).

        MuJoCo's free camera sits ``distance`` behind the looked-at point along its viewing
        direction (azimuth, elevation); its up vector is that direction turned 90 deg up.
        """
        azimuth, elevation = math.radians(self.azimuth), math.radians(self.elevation)
        forward = np.array([math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
                            math.sin(elevation)])
        up = np.array([-math.sin(elevation) * math.cos(azimuth), -math.sin(elevation) * math.sin(azimuth),
                       math.cos(elevation)])
        pose = np.eye(4)
        pose[:3, :3] = np.column_stack([np.cross(forward, up), -up, forward])
        pose[:3, 3] = np.array([self.ahead, 0.0, self.height]) - self.distance * forward
        return pose

    def calibration(self, width: int, height: int) -> Calibration:
        """Intrinsics of ``width`` x ``height`` px frames (square pixels, :data:`FOVY`) and the pose."""
        focal = 0.5 * height / math.tan(math.radians(FOVY) / 2)
        return Calibration(fx=focal, fy=focal, cx=(width - 1) / 2, cy=(height - 1) / 2, width=width, height=height,
                           base_from_camera=self.base_from_camera())


def _front() -> Camera:
    video = load_scene_config().video.camera
    return Camera("front", ahead=0.45, height=video.lookat_height, distance=1.5, azimuth=video.azimuth,
                  elevation=video.elevation)


CAMERAS: dict[str, Camera] = {
    "front": _front(),
    "top": Camera("top", ahead=0.4, height=0.0, distance=1.6, azimuth=0.0, elevation=-80.0),
}
"""The dataset's cameras by name."""


@dataclasses.dataclass
class Episode:
    """One filmed rollout.

    Attributes:
        layout: where it ran.
        state: (T, 8) simulated joints [rad] and finger distance [m] (:data:`STATE_NAMES`).
        action: (T, 8) the plan's commanded joints and finger distance at the same times.
        ee_pose: (T, 7) the simulated tool centre point in the robot base frame (:data:`EE_POSE_NAMES`).
        frames: camera name -> (T, H, W, 3) uint8 RGB.
        task: the task text.
        success: whether the replay achieved the action (the action's criteria on the whole rollout).
        reason: why it failed ("" on success).
    """

    layout: Layout
    state: np.ndarray
    action: np.ndarray
    ee_pose: np.ndarray
    frames: dict[str, np.ndarray]
    task: str
    success: bool = True
    reason: str = ""


class _Filming:
    """The ``video`` hook of ``replay_mujoco.simulate``: renders every camera and records the joints."""

    def __init__(self, cameras: list[Camera], base: np.ndarray, size: tuple[int, int]):
        self.cameras, self.base, self.size = cameras, base, size
        self.frames: dict[str, list[np.ndarray]] = {camera.name: [] for camera in cameras}
        self.state: list[np.ndarray] = []
        self.renderer = None

    def start(self, model):
        import mujoco  # optional extra: robot (imported after prefer_headless_gl picks its GL)

        model.vis.quality.offsamples = 0  # software GL: no multisampling, no shadow or reflection passes
        model.vis.global_.fovy = FOVY
        height, width = self.size
        model.vis.global_.offheight = max(model.vis.global_.offheight, height)
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        self.renderer = mujoco.Renderer(model, height, width)
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        self.views = [camera.view(self.base) for camera in self.cameras]
        self.arm = [model.joint(f"panda_joint{i}").qposadr[0] for i in range(1, 8)]
        self.fingers = [model.joint(name).qposadr[0] for name in FINGER_JOINTS]
        return self.renderer

    def frame(self, model, data) -> None:
        self.state.append(np.append(data.qpos[self.arm], data.qpos[self.fingers].sum()))
        for camera, view in zip(self.cameras, self.views):
            self.renderer.update_scene(data, view)
            self.frames[camera.name].append(self.renderer.render().copy())


def pose_vectors(poses: np.ndarray) -> np.ndarray:
    """(T, 7) position [m] and unit quaternion (w, x, y, z) of (T, 4, 4) poses; the quaternions'
    signs chosen continuous over T, the first with w >= 0."""
    quats = np.array([replay_mujoco.mujoco_quaternion(pose[:3, :3]) for pose in poses]).reshape(len(poses), 4)
    quats[0] *= 1.0 if quats[0, 0] >= 0 else -1.0
    for k in range(1, len(quats)):
        quats[k] *= 1.0 if quats[k] @ quats[k - 1] >= 0 else -1.0
    return np.column_stack([poses[:, :3, 3], quats])


def film(plan: RobotPlan, recon, *, fps: int, cameras: list[Camera], size: tuple[int, int],
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """Run ``plan`` in MuJoCo from its start to its end at ``fps``, rendering ``cameras`` at ``size`` (H, W) px.

    Returns:
        ``state`` (T, 8), ``action`` (T, 8) (the plan's command at the same times), ``ee_pose``
        (T, 7) (the tool centre point in the base frame) and camera name -> (T, H, W, 3) uint8 frames.
    """
    times = np.arange(0.0, plan.t[-1] + 1e-9, 1.0 / fps)
    filming = _Filming(cameras, plan.base, size)
    try:
        sim = replay_mujoco.simulate(plan, recon, times, video=filming)
    finally:
        if filming.renderer is not None:
            filming.renderer.close()
    action = np.column_stack([*(np.interp(times, plan.t, plan.q[:, i]) for i in range(7)),
                              np.interp(times, plan.t, plan.gripper)])
    ee_pose = pose_vectors(np.linalg.inv(plan.base) @ np.asarray(sim["tcp"]))
    frames = {name: np.stack(images) for name, images in filming.frames.items()}
    return np.asarray(filming.state), action, ee_pose, frames


@dataclasses.dataclass
class Attempt:
    """One layout tried, judged by its MuJoCo replay (not yet filmed).

    Attributes:
        layout: where it ran.
        reason: why it failed ("" on success): the planner's refusal, the replay's error or its failed checks.
        plan, recon: the plan and the skill's scene in the layout; None where it was not replayed.
    """

    layout: Layout
    reason: str
    plan: RobotPlan | None = None
    recon: Reconstruction | None = None

    @property
    def success(self) -> bool:
        """Whether the replay achieved the action."""
        return self.plan is not None and not self.reason


def rollouts(skill: Skill, *, seed: int = 0) -> Iterator[Attempt]:
    """Endless judged attempts of ``skill`` in the random layouts of ``seed`` (:func:`.layouts.layouts`).

    Raises:
        LayoutError: no layout of the skill fits the reachable table (from the sampler).
    """
    for layout in layouts(skill, seed=seed):
        yield attempt(skill, layout)


def attempt(skill: Skill, layout: Layout) -> Attempt:
    """Plan and replay ``skill`` in ``layout``: a refused layout or a failed replay is an attempt with its reason."""
    try:
        recon = apply_skill(skill, layout)
        plan = retarget(skill, layout=layout)
    except ValueError as error:  # LayoutError, PlanError, SkillError: the layout is refused
        return Attempt(layout, f"plan: {error}")
    try:
        result = replay(plan, recon, ENGINE)
    except ValueError as error:  # the plan's scene refused (its substitute object in the layout)
        return Attempt(layout, f"replay: {error}")
    failed = [name for name, ok in result.evaluation.checks.items() if not ok]
    return Attempt(layout, f"replay fails {', '.join(failed)}" if failed else "", plan, recon)


def film_attempt(tried: Attempt, task: str, *, fps: int, cameras: list[Camera], size: tuple[int, int]) -> Episode:
    """The :class:`Episode` of a planned attempt, filmed by ``cameras`` at ``size`` (H, W) px."""
    state, action, ee_pose, frames = film(tried.plan, tried.recon, fps=fps, cameras=cameras, size=size)
    return Episode(tried.layout, state, action, ee_pose, frames, task, success=tried.success, reason=tried.reason)
