"""Replaying a robot plan in Newton: the MuJoCo replay's scene, simulated by Newton's XPBD solver.

The scene is the one of :mod:`warpskill.robot.replay_mujoco`: the Panda URDF of
``example-robot-data`` (its collision meshes, loaded by Newton's URDF importer, which needs
``trimesh``), the table and static cuboids as fixed boxes, the manipulated cuboid as a free
body of :data:`~warpskill.robot.replay_mujoco.OBJECT_MASS` with the same friction. The
solver is :class:`newton.solvers.SolverXPBD` with Newton's own collision pipeline, so the
check does not reuse MuJoCo (Newton's ``SolverMuJoCo`` needs ``mujoco-warp`` and would run
MuJoCo's physics again).

Position control: the robot is a *kinematic* articulation that follows the plan exactly (its
links are posed by forward kinematics each step and carry their velocities into the
contacts), so only the cuboid is simulated. This is the ideal of MuJoCo's stiff position
actuators; it is used because, in Newton 1.8.0 on CPU, XPBD's revolute drives diverge on
this arm, Featherstone's explicit drives and penalty contacts blow up when the gripper
squeezes, and XPBD's friction against drive-pushed (dynamic) fingers lets the cuboid slip.
A force-limited gripper stops at the object: from the plan's grasp on, whenever the cuboid
is between the fingers, each finger stops :data:`SQUEEZE` inside the cuboid's current
width along the finger axis (so closing on it, holding it and opening from it never push
the fingers through it).
"""

from __future__ import annotations

import re

import numpy as np

from warpskill.reconstruction import Reconstruction
from warpskill.robot.model import ARM_JOINTS, FINGER_JOINTS, environment_boxes, make_scene, panda_urdf
from warpskill.robot.plan import RobotPlan
from warpskill.robot.replay_mujoco import FRICTION, OBJECT_MASS

TIMESTEP = 0.004  # [s]
ITERATIONS = 4  # XPBD iterations per step
CONTACT_GAP = 0.005  # [m] distance at which contacts are detected
SQUEEZE = 0.001  # [m] each closed finger stops this far inside the grasped cuboid
BETWEEN_FINGERS = 0.02  # [m] the cuboid counts as between the fingers up to this far off the pads' centre
# Links standing on (or just above) the table: their contacts with the environment are not simulated
# (panda_link0 is merged into the world when the fixed joints are collapsed).
_BASE_LINKS = ("panda_link0", "panda_link1")
_FINGER_LINKS = ("panda_leftfinger", "panda_rightfinger")


def _transform(T: np.ndarray):
    """A Warp transform from a 4x4 pose."""
    import warp as wp

    q = wp.quat_from_matrix(wp.mat33(*np.asarray(T[:3, :3], dtype=np.float32).reshape(9)))
    return wp.transform(wp.vec3(*np.asarray(T[:3, 3], dtype=np.float32)), q)


def _pose(row: np.ndarray) -> np.ndarray:
    """A 4x4 pose from a Newton ``body_q`` row (px, py, pz, qx, qy, qz, qw)."""
    x, y, z, w = row[3:7]
    R = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = row[:3]
    return T


def _label(labels, name: str) -> int:
    """Index of the entry of Newton's ``*_label`` list that ends with ``/name`` (or equals it)."""
    for i, label in enumerate(labels):
        if label == name or label.endswith("/" + name):
            return i
    raise KeyError(name)


def build_model(plan: RobotPlan, recon: Reconstruction, *, device: str | None = None):
    """The finalized ``newton.Model`` of the plan's scene and the indices the replay reads.

    Returns:
        ``(model, info)`` where ``info`` maps ``arm_dofs``, ``finger_dofs`` (joint_q indices),
        ``tcp_body``, ``object_body``, ``object_shape``, ``finger_bodies``, ``robot_bodies``.
    """
    import newton

    builder = newton.ModelBuilder()
    builder.default_shape_cfg = newton.ModelBuilder.ShapeConfig(mu=FRICTION, gap=CONTACT_GAP)
    text = re.sub(r"<visual>.*?</visual>", "", panda_urdf(collision="meshes"), flags=re.S)
    builder.add_urdf(text, xform=_transform(plan.base), floating=False, enable_self_collisions=False,
                     collapse_fixed_joints=True)
    joints = builder.joint_label
    arm_dofs = [builder.joint_qd_start[_label(joints, name)] for name in ARM_JOINTS]
    finger_dofs = [builder.joint_qd_start[_label(joints, name)] for name in FINGER_JOINTS]
    robot_bodies = list(range(builder.body_count))
    for body in robot_bodies:
        builder.body_flags[body] = int(newton.BodyFlags.KINEMATIC)
    q0 = np.concatenate([plan.q[0], [plan.gripper[0] / 2] * 2])
    for dof, value in zip(arm_dofs + finger_dofs, q0):
        builder.joint_q[dof] = float(value)
    bodies = builder.body_label
    base_bodies = {-1} | {i for i, label in enumerate(bodies) if label.rsplit("/", 1)[-1] in _BASE_LINKS}
    base_shapes = [s for s, b in enumerate(builder.shape_body) if b in base_bodies]
    finger_bodies = {_label(bodies, n) for n in _FINGER_LINKS}

    scene = make_scene(recon, base=plan.base)
    env_cfg = newton.ModelBuilder.ShapeConfig(mu=FRICTION, gap=CONTACT_GAP)
    for name, T, size in environment_boxes(scene):
        hx, hy, hz = (float(v) for v in size / 2)
        shape = builder.add_shape_box(-1, xform=_transform(T), hx=hx, hy=hy, hz=hz, cfg=env_cfg, label=name)
        for other in base_shapes:
            builder.add_shape_collision_filter_pair(other, shape)
    T0 = np.eye(4)
    T0[:3, :3] = recon.object_rot[0]
    T0[:3, 3] = recon.object_pos[0]
    size = np.asarray(recon.object_size, dtype=float)
    obj_cfg = newton.ModelBuilder.ShapeConfig(mu=FRICTION, gap=CONTACT_GAP,
                                              density=OBJECT_MASS / float(np.prod(size)))
    obj = builder.add_body(xform=_transform(T0), label="object")
    hx, hy, hz = (float(v) for v in size / 2)
    obj_shape = builder.add_shape_box(obj, hx=hx, hy=hy, hz=hz, cfg=obj_cfg, label="object")
    model = builder.finalize(device=device)
    info = {
        "arm_dofs": arm_dofs,
        "finger_dofs": finger_dofs,
        "tcp_body": _label(bodies, "panda_link7"),
        "robot_bodies": robot_bodies,
        "object_body": obj,
        "object_shape": obj_shape,
        "finger_bodies": sorted(finger_bodies),
    }
    return model, info


def simulate(plan: RobotPlan, recon: Reconstruction, times: np.ndarray, *, device: str | None = None) -> dict[str, np.ndarray]:
    """Run the plan; sample the TCP, the object and the finger contacts at plan ``times``.

    Returns the arrays of :func:`warpskill.robot.replay_mujoco.simulate`.
    """
    import newton
    import warp as wp

    wp.config.quiet = True
    with wp.ScopedDevice(device):
        model, info = build_model(plan, recon)
        robot = info["robot_bodies"]
        state_0, state_1, robot_state = model.state(), model.state(), model.state()
        newton.eval_fk(model, model.joint_q, model.joint_qd, state_0)
        # The fixed joints are collapsed into panda_link7: the TCP's offset from it comes
        # from the planned TCP at the first sample.
        tcp_offset = np.linalg.inv(_pose(state_0.body_q.numpy()[info["tcp_body"]])) @ plan.tcp[0]
        pipeline = newton.CollisionPipeline(model, reduce_contacts=False)
        contacts = pipeline.contacts()
        solver = newton.solvers.SolverXPBD(model, iterations=ITERATIONS)
        dofs = info["arm_dofs"] + info["finger_dofs"]
        joint_q = model.joint_q.numpy().copy()
        joint_qd = np.zeros_like(model.joint_qd.numpy())
        joint_q_wp, joint_qd_wp = wp.array(joint_q), wp.array(joint_qd)
        finger_bodies = set(info["finger_bodies"])
        shape_body = model.shape_body.numpy()
        size = np.asarray(recon.object_size, dtype=float)
        q_rate = np.gradient(plan.q, plan.t, axis=0)
        g_rate = np.gradient(plan.gripper, plan.t)
        gripping = plan.grasp_kind == "grasp"
        steps = int(np.ceil(times[-1] / TIMESTEP)) + 1
        out = {"tcp": [], "object_pos": [], "object_rot": [], "held": [], "q": []}
        k = 0
        for step in range(steps):
            t = step * TIMESTEP
            body_q, body_qd = state_0.body_q.numpy(), state_0.body_qd.numpy()
            # The robot is kinematic: its links follow the plan's joint positions exactly.
            opening = float(np.interp(t, plan.t, plan.gripper))
            rate = float(np.interp(t, plan.t, g_rate))
            tcp = _pose(body_q[info["tcp_body"]]) @ tcp_offset
            if gripping and t >= plan.grasp_time:
                obj = _pose(body_q[info["object_body"]])
                local = np.linalg.inv(tcp) @ obj
                width = float(np.abs(local[1, :3]) @ size)  # the cuboid along the finger axis
                between = np.all(np.abs(local[[0, 2], 3]) < BETWEEN_FINGERS + np.abs(local[[0, 2], :3]) @ size / 2)
                if between and opening < width - 2 * SQUEEZE:
                    opening, rate = width - 2 * SQUEEZE, 0.0
            joint_q[dofs] = [*(np.interp(t, plan.t, plan.q[:, i]) for i in range(7)), opening / 2, opening / 2]
            joint_qd[dofs] = [*(np.interp(t, plan.t, q_rate[:, i]) for i in range(7)), rate / 2, rate / 2]
            joint_q_wp.assign(joint_q)
            joint_qd_wp.assign(joint_qd)
            newton.eval_fk(model, joint_q_wp, joint_qd_wp, robot_state)
            body_q[robot] = robot_state.body_q.numpy()[robot]
            body_qd[robot] = robot_state.body_qd.numpy()[robot]
            state_0.body_q.assign(body_q)
            state_0.body_qd.assign(body_qd)
            pipeline.collide(state_0, contacts)
            while k < len(times) and times[k] <= t + 1e-9:
                P = _pose(body_q[info["object_body"]])
                out["tcp"].append(_pose(body_q[info["tcp_body"]]) @ tcp_offset)
                out["object_pos"].append(P[:3, 3])
                out["object_rot"].append(P[:3, :3])
                touched = {int(shape_body[s]) for s in _touching(contacts, info["object_shape"], body_q, shape_body)}
                out["held"].append(float(finger_bodies <= touched))
                out["q"].append(joint_q[info["arm_dofs"]].copy())
                k += 1
            if k >= len(times):
                break
            state_0.clear_forces()
            solver.step(state_0, state_1, None, contacts, TIMESTEP)
            state_0, state_1 = state_1, state_0
    return {key: np.asarray(value) for key, value in out.items()}


def _touching(contacts, shape: int, body_q: np.ndarray, shape_body: np.ndarray, *, tolerance: float = 1e-3) -> set[int]:
    """Shapes within ``tolerance`` [m] of ``shape`` (or penetrating it)."""
    n = int(contacts.rigid_contact_count.numpy()[0])
    a = contacts.rigid_contact_shape0.numpy()[:n]
    b = contacts.rigid_contact_shape1.numpy()[:n]
    sel = np.flatnonzero((a == shape) | (b == shape))
    if len(sel) == 0:
        return set()
    points = []
    for key, shapes in (("rigid_contact_point0", a), ("rigid_contact_point1", b)):
        local = getattr(contacts, key).numpy()[sel]
        world = local.copy()
        for j, s in enumerate(shapes[sel]):
            body = shape_body[s]
            if body >= 0:
                T = _pose(body_q[body])
                world[j] = T[:3, :3] @ local[j] + T[:3, 3]
        points.append(world)
    normal = contacts.rigid_contact_normal.numpy()[sel]
    margin = contacts.rigid_contact_margin0.numpy()[sel] + contacts.rigid_contact_margin1.numpy()[sel]
    distance = np.einsum("ij,ij->i", normal, points[1] - points[0]) - margin
    close = sel[distance <= tolerance]
    return {int(s) for s in a[close]} | {int(s) for s in b[close]} - {shape}
