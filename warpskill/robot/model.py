"""The Franka Panda and its scene: the URDF shipped by ``example-robot-data``, the table, the cuboids.

Everything is expressed in the reconstruction's world frame (``docs/formats.md``: z up, the table
top is z = 0). The robot's base stands on the table at a pose given by a :class:`Placement`
relative to the reconstructed scene; the manipulated cuboid and the static cuboids keep
their reconstructed poses. Nothing is downloaded: the URDF and meshes come from the
installed ``example-robot-data`` wheel, its ``package://`` paths resolved to that folder.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.metadata
import math
import re
from pathlib import Path

import numpy as np

from warpskill.contract.reconstruction import Reconstruction
from warpskill.geometry import rot_z
from warpskill.nouns.typical import is_open_topped
from warpskill.robot.scene_config import load_scene_config

ARM_JOINTS: tuple[str, ...] = tuple(f"panda_joint{i}" for i in range(1, 8))
"""The seven arm joints, base to wrist."""

FINGER_JOINTS: tuple[str, ...] = ("panda_finger_joint1", "panda_finger_joint2")
"""The two prismatic finger joints; each opens by half the gripper opening."""

TCP_FRAME = "panda_hand_tcp"
"""The tool centre point: between the finger pads; its local +z is the approach direction."""

HOME_Q = np.array([0.0, -0.785398, 0.0, -2.35619, 0.0, 1.5707, 0.785398])
"""The SRDF's ``default`` arm configuration [rad]: the gripper above the table, pointing down."""

MAX_OPENING = 0.08
"""Largest gripper opening [m] (each finger 0 .. 0.04 m)."""

RIM_WALL = 0.005
"""[m] wall (and bottom) thickness of an open-topped object (:func:`object_boxes`): a cup's or a bowl's."""

FINGER_SPEED = 0.2
"""Largest speed [m/s] of each finger (the URDF's limit)."""

_PACKAGE_PREFIX = "package://example-robot-data/robots/"

# Link pairs the SRDF declares as never colliding (or adjacent): no self-collision check.
_SRDF_DISABLED = {
    frozenset(pair)
    for pair in [
        ("panda_hand", "panda_leftfinger"), ("panda_hand", "panda_link3"), ("panda_hand", "panda_link4"),
        ("panda_hand", "panda_link5"), ("panda_hand", "panda_link6"), ("panda_hand", "panda_link7"),
        ("panda_hand", "panda_rightfinger"), ("panda_leftfinger", "panda_link3"),
        ("panda_leftfinger", "panda_link4"), ("panda_leftfinger", "panda_link6"),
        ("panda_leftfinger", "panda_link7"), ("panda_leftfinger", "panda_rightfinger"),
        ("panda_link0", "panda_link1"), ("panda_link0", "panda_link2"), ("panda_link0", "panda_link3"),
        ("panda_link0", "panda_link4"), ("panda_link1", "panda_link2"), ("panda_link1", "panda_link3"),
        ("panda_link1", "panda_link4"), ("panda_link2", "panda_link3"), ("panda_link2", "panda_link4"),
        ("panda_link3", "panda_link4"), ("panda_link3", "panda_link5"), ("panda_link3", "panda_link6"),
        ("panda_link3", "panda_link7"), ("panda_link3", "panda_rightfinger"), ("panda_link4", "panda_link5"),
        ("panda_link4", "panda_link6"), ("panda_link4", "panda_link7"), ("panda_link4", "panda_rightfinger"),
        ("panda_link5", "panda_link6"), ("panda_link5", "panda_link7"), ("panda_link6", "panda_link7"),
        ("panda_link6", "panda_rightfinger"), ("panda_link7", "panda_rightfinger"),
    ]
}
_ROBOT_LINKS = (
    "panda_link0", "panda_link1", "panda_link2", "panda_link3", "panda_link4", "panda_link5", "panda_link6",
    "panda_link7", "panda_hand", "panda_leftfinger", "panda_rightfinger",
)
# Links that can reach the table or a static box (the base links stand on the table).
_ENVIRONMENT_CHECKED = ("panda_link4", "panda_link5", "panda_link6", "panda_link7", "panda_hand",
                        "panda_leftfinger", "panda_rightfinger")


class RobotModelError(RuntimeError):
    """The robot description cannot be found or loaded."""


@dataclasses.dataclass(frozen=True)
class Placement:
    """Where the robot stands relative to the reconstructed scene.

    Attributes:
        offset: (x, y) [m] of the scene centre (the centre of the xy bounding box of the
            manipulated object's path and the static objects) in the robot base frame.
            The default puts it 0.5 m in front of the base, the Panda's comfortable reach.
        yaw: direction [rad] of the robot's forward (base +x) axis in the world, about z.
            The default, pi/2, faces the robot along world +y: it stands on the camera's
            side, where the demonstrating arm came from.
    """

    offset: tuple[float, float] = (0.5, 0.0)
    yaw: float = math.pi / 2


@dataclasses.dataclass(frozen=True)
class Scene:
    """The robot's world: base pose, table and cuboids (world frame of ``docs/formats.md``).

    Attributes:
        base: (4, 4) pose of the robot base (``panda_link0``) in the world.
        table_pos: (3,) centre [m] of the table box (its top at z = 0).
        table_size: (3,) edge lengths [m] of the table box.
        object_pos, object_rot, object_size: the manipulated cuboid at the first frame.
        static_pos, static_rot, static_size: (K, 3), (K, 3, 3), (K, 3) static cuboids.
    """

    base: np.ndarray
    table_pos: np.ndarray
    table_size: np.ndarray
    object_pos: np.ndarray
    object_rot: np.ndarray
    object_size: np.ndarray
    static_pos: np.ndarray
    static_rot: np.ndarray
    static_size: np.ndarray


def make_scene(recon: Reconstruction, placement: Placement | None = None, *, base: np.ndarray | None = None) -> Scene:
    """The robot scene of a reconstruction: base placed by ``placement`` (or at ``base``), table under it all."""
    placement = placement or Placement()
    points = [recon.object_pos[:, :2], recon.static_pos[:, :2]]
    xy = np.concatenate(points, 0)
    centre = 0.5 * (xy.min(0) + xy.max(0))
    if base is None:
        rot = rot_z(placement.yaw)
        base = np.eye(4)
        base[:3, :3] = rot
        base[:2, 3] = centre - rot[:2, :2] @ np.asarray(placement.offset, float)
    # The table spans the base and the scene, with margin around both.
    table_size = np.array(load_scene_config().table.size)
    table_xy = 0.5 * (base[:2, 3] + centre)
    table_pos = np.array([table_xy[0], table_xy[1], -table_size[2] / 2])
    return Scene(
        base=base,
        table_pos=table_pos,
        table_size=table_size,
        object_pos=recon.object_pos[0].copy(),
        object_rot=recon.object_rot[0].copy(),
        object_size=recon.object_size.copy(),
        static_pos=recon.static_pos.copy(),
        static_rot=recon.static_rot.copy(),
        static_size=recon.static_size.copy(),
    )


def object_boxes(recon: Reconstruction) -> list[tuple[np.ndarray, np.ndarray]]:
    """The manipulated object as boxes in its own frame: ``(centre (3,), half extents (3,))`` [m] each.

    The cuboid; an open vessel (its noun :func:`~warpskill.nouns.typical.is_open_topped`) is
    the cuboid open at the face that is up in the first frame: its bottom and four side walls,
    :data:`RIM_WALL` thick, so that a rim grasp's inner finger goes inside.
    """
    half = np.asarray(recon.object_size, float) / 2
    if not is_open_topped(str(recon.object_noun)):
        return [(np.zeros(3), half)]
    up_world = recon.object_rot[0][2]  # world up in the object's frame
    up = int(np.argmax(np.abs(up_world)))
    sides = [(up, -math.copysign(1.0, up_world[up]))]  # the bottom
    sides += [(j, sign) for j in range(3) if j != up for sign in (1.0, -1.0)]  # the walls
    boxes = []
    for axis, side in sides:
        centre, extent = np.zeros(3), half.copy()
        centre[axis], extent[axis] = side * (half[axis] - RIM_WALL / 2), RIM_WALL / 2
        boxes.append((centre, extent))
    return boxes


@functools.cache
def panda_description_dir() -> Path:
    """Folder of the Panda description (``urdf/``, ``srdf/``, ``meshes/``) in ``example-robot-data``.

    Raises:
        RobotModelError: the package is not installed or lacks the Panda.
    """
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        raise RobotModelError(
            "the Panda model needs the 'example-robot-data' package: pip install 'warpskill[robot]'"
        ) from None
    folder = Path(dist.locate_file("cmeel.prefix/share/example-robot-data/robots/panda_description"))
    if not (folder / "urdf" / "panda.urdf").is_file():
        raise RobotModelError(f"example-robot-data is installed but has no Panda URDF under {folder}")
    return folder


def panda_urdf(*, collision: str = "primitives") -> str:
    """The Panda URDF text with every ``package://`` path made absolute.

    Args:
        collision: ``"primitives"`` (spheres and cylinders that cover each link, used by the
            planner; each finger's tip is the simulated rubber pad, :func:`_pad_tips`) or
            ``"meshes"`` (the convex collision meshes and the fingers' boxes, used by the simulators).
    """
    if collision not in ("primitives", "meshes"):
        raise ValueError(f"collision must be 'primitives' or 'meshes', got {collision!r}")
    folder = panda_description_dir()
    name = "panda_collision.urdf" if collision == "primitives" else "panda.urdf"
    text = (folder / "urdf" / name).read_text()
    if collision == "primitives":
        text = _pad_tips(text)
    return text.replace(_PACKAGE_PREFIX, str(folder.parent) + "/")


_TIP_SPHERE = re.compile(r'<origin xyz="0 (-?)15e-3 45e-3"/>(\s*)<geometry>\s*<sphere radius="0.015"/>')


def _pad_tips(text: str) -> str:
    """The primitives' URDF ``text`` with each finger's tip sphere replaced by the rubber pad box the
    simulators collide (``panda.urdf``'s): the sphere (radius 15 mm) reaches 14.5 mm beyond the TCP
    along the approach, the pad only 9.5 mm, so that the planner kept a flat object's pads above
    its top (a 1 cm card was never touched).

    Raises:
        RobotModelError: the file has no such tip spheres (another ``example-robot-data``).
    """
    out, count = _TIP_SPHERE.subn(r'<origin xyz="0 \g<1>7.58e-3 45.25e-3"/>\2<geometry><box size="17.5e-3 15.2e-3 18.5e-3"/>',
                                  text)
    if count != 2:
        raise RobotModelError(f"the Panda's collision primitives have {count} fingertip spheres, not 2")
    return out


def _origin(T: np.ndarray) -> str:
    """A URDF ``<origin>`` for the 4x4 pose ``T``."""
    R = T[:3, :3]
    roll = math.atan2(R[2, 1], R[2, 2])
    pitch = math.asin(max(-1.0, min(1.0, -R[2, 0])))
    yaw = math.atan2(R[1, 0], R[0, 0])
    x, y, z = T[:3, 3]
    return f'<origin xyz="{x:.9g} {y:.9g} {z:.9g}" rpy="{roll:.9g} {pitch:.9g} {yaw:.9g}"/>'


def environment_boxes(scene: Scene) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The fixed boxes of the scene as (name, (4, 4) world pose, (3,) size): the table and statics."""
    boxes = []
    table = np.eye(4)
    table[:3, 3] = scene.table_pos
    boxes.append(("table", table, scene.table_size))
    for k in range(len(scene.static_pos)):
        T = np.eye(4)
        T[:3, :3] = scene.static_rot[k]
        T[:3, 3] = scene.static_pos[k]
        boxes.append((f"static{k}", T, scene.static_size[k]))
    return boxes


def planner_urdf(scene: Scene) -> str:
    """The Panda (collision primitives) with the table and static cuboids as fixed links of its base.

    Fixing the environment to the base lets the planner's self-collision avoidance keep the
    arm off the table and the static objects too.
    """
    base_inv = np.linalg.inv(scene.base)
    extra = []
    for name, T, size in environment_boxes(scene):
        sx, sy, sz = size
        extra.append(
            f'<link name="{name}"><collision><origin xyz="0 0 0"/><geometry><box size="{sx:.9g} {sy:.9g} {sz:.9g}"/>'
            f'</geometry></collision></link>'
            f'<joint name="{name}_joint" type="fixed"><parent link="panda_link0"/><child link="{name}"/>'
            f"{_origin(base_inv @ T)}</joint>"
        )
    return panda_urdf(collision="primitives").replace("</robot>", "\n".join(extra) + "\n</robot>")


def collision_pairs(scene: Scene) -> list[tuple[str, str]]:
    """Link pairs checked for collisions: the arm against itself (less the SRDF's) and the environment."""
    pairs = []
    for i, a in enumerate(_ROBOT_LINKS):
        for b in _ROBOT_LINKS[i + 1 :]:
            if frozenset((a, b)) not in _SRDF_DISABLED and not {a, b} <= {"panda_link0", "panda_link1"}:
                pairs.append((a, b))
    for name, _, _ in environment_boxes(scene):
        pairs += [(link, name) for link in _ENVIRONMENT_CHECKED]
    return pairs


def mujoco_urdf() -> str:
    """The Panda URDF (collision meshes, no visuals: MuJoCo reads no ``.dae``) with a MuJoCo compiler tag."""
    folder = panda_description_dir()
    text = (folder / "urdf" / "panda.urdf").read_text()
    text = re.sub(r"<visual>.*?</visual>", "", text, flags=re.S)
    text = text.replace(_PACKAGE_PREFIX + "panda_description/meshes/collision/", "")
    text = re.sub(
        r"<robot([^>]*)>",
        f'<robot name="panda"><mujoco><compiler meshdir="{folder / "meshes" / "collision"}" '
        'discardvisual="false" fusestatic="false" balanceinertia="true"/></mujoco>',
        text,
        count=1,
    )
    return text
