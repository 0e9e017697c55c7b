"""Forward kinematics of the Panda and its collision geometry, to draw the arm where it was.

Both come from MuJoCo's compiled model of the URDF the replay simulates
(:func:`~warpskill.robot.model.mujoco_urdf`: collision meshes, base at the origin), so a
link drawn at :func:`link_poses` is exactly where :func:`warpskill.robot.replay` has it for
the same joints. Link frames are the URDF's (MuJoCo body frames); world frame of
``docs/formats.md`` (z up, metres).
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from warpskill.robot.model import ARM_JOINTS, FINGER_JOINTS, mujoco_urdf

__all__ = ["LinkShape", "link_poses", "link_shapes"]

_SHAPE_KINDS = {2: "sphere", 3: "capsule", 4: "ellipsoid", 5: "cylinder", 6: "box", 7: "mesh"}  # mjtGeom


@dataclasses.dataclass(frozen=True)
class LinkShape:
    """One collision shape of a link.

    Attributes:
        kind: ``"mesh"``, ``"box"``, ``"sphere"``, ``"capsule"``, ``"cylinder"`` or
            ``"ellipsoid"`` (the Panda has meshes and, on its fingers, boxes).
        pose: (4, 4) pose of the shape in its link's frame.
        size: (3,) MuJoCo's geom size [m] in the shape's frame: half edges (box, ellipsoid),
            radius (sphere), radius and half length along z (capsule, cylinder).
        vertices: (V, 3) mesh vertices [m] in the shape's frame; None but for meshes.
        triangles: (T, 3) int32 vertex indices, counter-clockwise seen from outside; None
            but for meshes.
    """

    kind: str
    pose: np.ndarray
    size: np.ndarray
    vertices: np.ndarray | None = None
    triangles: np.ndarray | None = None


@functools.cache
def _model():
    """The compiled MuJoCo model of the Panda alone (cached: about 20 ms to build)."""
    import mujoco  # optional extra: robot (imported after prefer_headless_gl picks its GL)

    return mujoco.MjModel.from_xml_string(mujoco_urdf())


def _bodies(model) -> list[tuple[int, str]]:
    return [(i, model.body(i).name) for i in range(1, model.nbody)]  # body 0 is MuJoCo's world


def link_poses(
    q: np.ndarray, gripper: np.ndarray | float = 0.0, base: np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """World poses of every Panda link for F configurations.

    Args:
        q: (F, 7) or (7,) arm joint positions [rad] (``panda_joint1`` .. ``panda_joint7``).
        gripper: (F,) or scalar gripper opening [m]; each finger opens by half of it.
        base: (4, 4) world pose of the base (``panda_link0``), as ``RobotPlan.base``;
            None for the identity.

    Returns:
        Link name (``panda_link0`` .. ``panda_link8``, ``panda_hand``, ``panda_hand_tcp``,
        ``panda_leftfinger``, ``panda_rightfinger``) -> (F, 4, 4) world poses ((4, 4)
        when ``q`` is (7,)).

    Raises:
        ValueError: arrays of the wrong shape.
        ModuleNotFoundError: MuJoCo is not installed.
        RobotModelError: ``example-robot-data`` (the Panda) is not installed.
    """
    import mujoco  # optional extra: robot (imported after prefer_headless_gl picks its GL)

    q = np.asarray(q, dtype=float)
    single = q.ndim == 1
    q = np.atleast_2d(q)
    if q.ndim != 2 or q.shape[1] != len(ARM_JOINTS):
        raise ValueError(f"q: expected shape (F, 7) or (7,), got {np.shape(q)}")
    count = len(q)
    gripper = np.asarray(gripper, dtype=float)
    if gripper.ndim > 1 or (gripper.ndim == 1 and gripper.shape != (count,)):
        raise ValueError(f"gripper: expected a scalar or shape ({count},), got {gripper.shape}")
    opening = np.broadcast_to(gripper, (count,))
    base = np.eye(4) if base is None else np.asarray(base, dtype=float)
    if base.shape != (4, 4):
        raise ValueError(f"base: expected shape (4, 4), got {base.shape}")
    model = _model()
    data = mujoco.MjData(model)
    arm = [model.joint(name).qposadr[0] for name in ARM_JOINTS]
    fingers = [model.joint(name).qposadr[0] for name in FINGER_JOINTS]
    bodies = _bodies(model)
    ids = [i for i, _ in bodies]
    local = np.zeros((count, len(ids), 4, 4))
    local[:, :, 3, 3] = 1.0
    for k in range(count):
        data.qpos[arm] = q[k]
        data.qpos[fingers] = opening[k] / 2.0
        mujoco.mj_kinematics(model, data)
        local[k, :, :3, :3] = data.xmat[ids].reshape(-1, 3, 3)
        local[k, :, :3, 3] = data.xpos[ids]
    world = base @ local  # the model's base stands at the origin
    return {name: world[0, j] if single else world[:, j] for j, (_, name) in enumerate(bodies)}


def link_shapes() -> dict[str, list[LinkShape]]:
    """The collision shapes of every Panda link (those the replay simulates), in link frames.

    Returns:
        Link name -> its shapes (an empty list for a link without any).

    Raises:
        ModuleNotFoundError: MuJoCo is not installed.
        RobotModelError: ``example-robot-data`` (the Panda) is not installed.
    """
    import mujoco  # optional extra: robot (imported after prefer_headless_gl picks its GL)

    model = _model()
    shapes: dict[str, list[LinkShape]] = {name: [] for _, name in _bodies(model)}
    for g in range(model.ngeom):
        body = int(model.geom_bodyid[g])
        if body == 0:
            continue
        pose = np.eye(4)
        rotation = np.zeros(9)
        mujoco.mju_quat2Mat(rotation, model.geom_quat[g])
        pose[:3, :3] = rotation.reshape(3, 3)
        pose[:3, 3] = model.geom_pos[g]
        kind = _SHAPE_KINDS.get(int(model.geom_type[g]))
        if kind is None:
            continue  # planes and height fields: none on the Panda
        vertices = triangles = None
        if kind == "mesh":
            mesh = int(model.geom_dataid[g])
            v0, nv = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
            f0, nf = model.mesh_faceadr[mesh], model.mesh_facenum[mesh]
            vertices = np.array(model.mesh_vert[v0 : v0 + nv], dtype=float)
            triangles = np.array(model.mesh_face[f0 : f0 + nf], dtype=np.int32)
        shapes[model.body(body).name].append(
            LinkShape(kind, pose, np.array(model.geom_size[g], dtype=float), vertices, triangles)
        )
    return shapes
