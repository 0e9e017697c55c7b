"""The robot scene's description, ``assets/robot_scene.toml``, as typed, frozen settings.

One file describes what the MuJoCo replay, the Newton replay, the planner's table and the
replay video share: the table, the manipulated object, the contacts, the Panda's drives,
each engine's step and solver options, the video's camera and lights. It is read once
(:func:`load_scene_config`); every key is required and unknown keys are errors, so a typo
in the file fails loudly instead of silently keeping a default.

TOML (read with ``tomllib``, Python >= 3.11, or the ``tomli`` package on 3.10) rather than
JSON because the file carries a comment with the unit of every value.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import typing
from pathlib import Path

import numpy as np

from warpskill import assets

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: the tomli package, a dependency there
    import tomli as tomllib

SCENE_ASSET = "robot_scene.toml"
"""Name of the scene description in :mod:`warpskill.assets`."""

Vec = tuple[float, ...]


@dataclasses.dataclass(frozen=True)
class TableConfig:
    """The table box; its top is the world plane z = 0.

    Attributes:
        size: (3,) edge lengths [m].
        rgba: colour.
    """

    size: Vec
    rgba: Vec


@dataclasses.dataclass(frozen=True)
class StaticConfig:
    """The static cuboids (their sizes and poses come from the reconstruction).

    Attributes:
        rgba: colour.
    """

    rgba: Vec


@dataclasses.dataclass(frozen=True)
class ObjectConfig:
    """The manipulated cuboid (its size and poses come from the reconstruction).

    Attributes:
        mass: [kg].
        rgba: colour.
    """

    mass: float
    rgba: Vec


@dataclasses.dataclass(frozen=True)
class ContactConfig:
    """Every contact of the scene.

    Attributes:
        friction: sliding friction coefficient [-] (both engines).
        torsional_friction: MuJoCo's torsional friction [m].
        rolling_friction: MuJoCo's rolling friction [m].
        condim: MuJoCo's contact dimensionality.
    """

    friction: float
    torsional_friction: float
    rolling_friction: float
    condim: int

    @property
    def mujoco_friction(self) -> list[float]:
        """MuJoCo's geom ``friction`` triple (sliding, torsional, rolling)."""
        return [self.friction, self.torsional_friction, self.rolling_friction]


@dataclasses.dataclass(frozen=True)
class PandaConfig:
    """The Panda's position drives and joints.

    Attributes:
        gravity_compensation: the links carry an upward force ``m g`` at their centre of mass.
        arm_kp: (7,) arm stiffness [N m / rad], joints 1..7.
        arm_kv_ratio: arm damping gain over stiffness [s] (see :attr:`arm_kv`).
        arm_torque_limit: (7,) arm drive torque limits [N m].
        arm_armature: armature of each arm joint [kg m^2].
        arm_damping: passive damping of each arm joint [N m s / rad].
        finger_kp: stiffness of each finger drive [N / m].
        finger_kv: damping gain of each finger drive [N s / m].
        finger_damping: passive damping of each finger joint [N s / m].
        grip_force: force limit of each finger drive [N]: a closed command squeezes this hard.
        rgba: colour of the links in the video.
    """

    gravity_compensation: bool
    arm_kp: Vec
    arm_kv_ratio: float
    arm_torque_limit: Vec
    arm_armature: float
    arm_damping: float
    finger_kp: float
    finger_kv: float
    finger_damping: float
    grip_force: float
    rgba: Vec

    @property
    def arm_kv(self) -> np.ndarray:
        """(7,) arm damping gains [N m s / rad]: ``arm_kv_ratio * arm_kp``."""
        return self.arm_kv_ratio * np.array(self.arm_kp)


@dataclasses.dataclass(frozen=True)
class MujocoConfig:
    """MuJoCo's options.

    Attributes:
        timestep: physics step [s].
        cone: friction cone, ``"elliptic"`` or ``"pyramidal"``.
        impratio: frictional-to-normal constraint impedance ratio [-].
        integrator: ``"euler"``, ``"rk4"``, ``"implicit"`` or ``"implicitfast"``.
        object_contact_timeconst: time constant [s] of the object's contacts (its ``solref``,
            critically damped; the object's geoms have the higher ``priority``, so MuJoCo takes
            it rather than averaging it with the other geom's default 0.02 s): with the default
            a 40 N squeeze sinks a finger pad about 4 mm into a 2 cm thin object, which then
            rides over its top edge (averaged, 3 mm into a 1 cm card as the fingers struck it);
            at least twice ``timestep``.
    """

    timestep: float
    cone: str
    impratio: float
    integrator: str
    object_contact_timeconst: float


@dataclasses.dataclass(frozen=True)
class NewtonConfig:
    """Newton's ``SolverSteel`` options.

    Attributes:
        timestep: physics step [s].
        iterations: projected Gauss-Seidel iterations per step.
        contact_gap: distance at which contacts are detected [m].
        row_capacity: constraint rows of the robot per step.
        limit_gap: a joint limit's row is created this close to it [rad or m].
        capture_graph: replay each physics step (drive targets, solver step, collision
            detection) as a captured Warp graph (a CUDA graph on a GPU, Warp's CPU graph
            on the CPU) instead of launching its kernels one by one from Python.
    """

    timestep: float
    iterations: int
    contact_gap: float
    row_capacity: int
    limit_gap: float
    capture_graph: bool


@dataclasses.dataclass(frozen=True)
class CameraConfig:
    """The video's MuJoCo free camera, placed relative to the robot and the scene.

    Attributes:
        lookat_blend: the lookat point lies this fraction [-] of the way from the robot base
            (0) to the scene centre (1) ...
        lookat_height: ... this high [m] above the table.
        distance: from the lookat point [m].
        azimuth: of the viewing direction [deg], from the robot's forward (base +x) axis, about z.
        elevation: of the viewing direction [deg] (negative: looking down).
    """

    lookat_blend: float
    lookat_height: float
    distance: float
    azimuth: float
    elevation: float


@dataclasses.dataclass(frozen=True)
class HeadlightConfig:
    """MuJoCo's headlight (at the camera); RGB intensities in [0, 1].

    Attributes:
        ambient, diffuse, specular: (3,) each.
    """

    ambient: Vec
    diffuse: Vec
    specular: Vec


@dataclasses.dataclass(frozen=True)
class LightConfig:
    """A directional light of the video.

    Attributes:
        direction: (3,) direction the light shines in, world frame (need not be unit).
        diffuse, specular: (3,) RGB intensities in [0, 1].
        castshadow: whether it casts shadows.
    """

    direction: Vec
    diffuse: Vec
    specular: Vec
    castshadow: bool


@dataclasses.dataclass(frozen=True)
class VideoConfig:
    """The MuJoCo replay video.

    Attributes:
        width, height: frame size [px].
        fps: frame rate [1/s].
        background: (3,) RGB of the backdrop's top (a gradient to white at the bottom).
        camera: the camera.
        headlight: the light at the camera.
        lights: directional lights.
    """

    width: int
    height: int
    fps: float
    background: Vec
    camera: CameraConfig
    headlight: HeadlightConfig
    lights: tuple[LightConfig, ...]


@dataclasses.dataclass(frozen=True)
class RobotSceneConfig:
    """The robot scene of ``assets/robot_scene.toml`` (one attribute per TOML table).

    Attributes:
        table, static, object, contact, panda, mujoco, newton, video: the sections.
    """

    table: TableConfig
    static: StaticConfig
    object: ObjectConfig
    contact: ContactConfig
    panda: PandaConfig
    mujoco: MujocoConfig
    newton: NewtonConfig
    video: VideoConfig


class SceneConfigError(ValueError):
    """The scene description is missing a key, has an unknown one or a value of the wrong type."""


def _convert(value, kind, where: str):
    """``value`` of the TOML file as the field type ``kind`` (checked)."""
    if dataclasses.is_dataclass(kind):
        return _section(kind, value, where)
    origin = typing.get_origin(kind)
    if origin is tuple:
        if not isinstance(value, list):
            raise SceneConfigError(f"{where}: expected a list, got {value!r}")
        item = typing.get_args(kind)[0]
        return tuple(_convert(v, item, f"{where}[{i}]") for i, v in enumerate(value))
    if kind is bool:
        ok = isinstance(value, bool)
    elif kind is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif kind is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    else:
        ok = isinstance(value, kind)
    if not ok:
        raise SceneConfigError(f"{where}: expected {kind.__name__}, got {value!r}")
    return kind(value)


def _section(cls, table, where: str):
    """The dataclass ``cls`` from the TOML table ``table``: every field required, no other key."""
    if not isinstance(table, dict):
        raise SceneConfigError(f"{where}: expected a table, got {table!r}")
    hints = typing.get_type_hints(cls)
    names = [field.name for field in dataclasses.fields(cls)]
    missing = [name for name in names if name not in table]
    unknown = sorted(set(table) - set(names))
    if missing or unknown:
        problems = [f"missing {', '.join(missing)}"] * bool(missing) + [f"unknown {', '.join(unknown)}"] * bool(unknown)
        raise SceneConfigError(f"{where}: {'; '.join(problems)}")
    return cls(**{name: _convert(table[name], hints[name], f"{where}.{name}") for name in names})


def read_scene_config(path: str | os.PathLike) -> RobotSceneConfig:
    """The scene description at ``path`` (a TOML file laid out as ``assets/robot_scene.toml``).

    Raises:
        SceneConfigError: naming the key: a missing or unknown key, a value of the wrong type,
            or a file that is not TOML.
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except ValueError as exc:  # tomllib.TOMLDecodeError is a ValueError
        if isinstance(exc, SceneConfigError):
            raise
        raise SceneConfigError(f"{path}: not valid TOML ({exc})") from None
    config = _section(RobotSceneConfig, data, str(path))
    if len(config.panda.arm_kp) != 7 or len(config.panda.arm_torque_limit) != 7:
        raise SceneConfigError(f"{path}: panda.arm_kp and panda.arm_torque_limit need 7 values (joints 1..7)")
    if config.mujoco.object_contact_timeconst < 2 * config.mujoco.timestep:
        raise SceneConfigError(f"{path}: mujoco.object_contact_timeconst ({config.mujoco.object_contact_timeconst} s) "
                               f"must be at least twice mujoco.timestep ({config.mujoco.timestep} s)")
    return config


@functools.cache
def load_scene_config() -> RobotSceneConfig:
    """The installed ``assets/robot_scene.toml``, read once (cached)."""
    return read_scene_config(assets.path(SCENE_ASSET))
