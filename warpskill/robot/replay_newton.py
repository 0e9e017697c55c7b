"""Replaying a robot plan in Newton: the MuJoCo replay's scene and position control, simulated by Newton.

The scene is the one of :mod:`warpskill.robot.replay_mujoco`: the Panda URDF of
``example-robot-data`` (its collision meshes, loaded by Newton's URDF importer, which needs
``trimesh``), the table and static cuboids as fixed boxes, the manipulated cuboid as a free
body of ``object.mass`` (an open vessel's: its bottom and walls, :func:`~warpskill.robot.model.object_boxes`),
every contact with ``contact.friction`` (``assets/robot_scene.toml``). Newton's own collision pipeline makes the
contacts, so the check does not reuse MuJoCo.

The robot is a dynamic articulation under position control, as in MuJoCo: every arm joint
has a PD drive towards the plan's joint position (interpolated linearly at every physics
step) with MuJoCo's gains (``panda.arm_kp``, ``panda.arm_kv``) and
torque limits (``panda.arm_torque_limit``), armature and joint damping, and the links carry
gravity compensation (a constant upward force ``m g`` at each link's centre of mass). Each
finger is an independent prismatic joint (the URDF's mimic tag is dropped, as MuJoCo's
importer ignores it) with a PD drive towards half the planned opening whose force is capped
at ``panda.grip_force``: a closed command squeezes the cuboid
and the finger stops at it. The cuboid moves only through contacts with the simulated
fingers and hand. The drives track the plan the way MuJoCo's do (a lag of about
``arm_kv / arm_kp`` times the joint speed: 0.05 to 0.2 rad at the fastest moves of the
synthetic plans, Newton's joints within 0.005 rad of MuJoCo's unless the hand jams against
the cuboid or the table), so the replayed joints follow the plan closely but not exactly.

Solver: :class:`newton.solvers.SolverSteel` (experimental in Newton 1.8): reduced-coordinate
articulated dynamics whose drives are integrated implicitly in the mass matrix, with
contacts, friction and joint limits solved by projected Gauss-Seidel; its persistent
friction patches hold a squeezed cuboid without creep. It runs at MuJoCo's
timestep (``newton.timestep``) on Warp's CPU device (and, untested here, on CUDA). Newton 1.8's other
options were found to fail on CPU for this scene: ``SolverXPBD``'s revolute drives diverged
on this arm and its friction let the cuboid slip between drive-pushed fingers,
``SolverFeatherstone``'s explicit drives with penalty contacts blew up when the gripper
squeezed, and ``SolverMuJoCo`` needs ``mujoco-warp`` (and would run MuJoCo's physics
again). Steel at 4 ms steps halves the replay time but doubles the largest deviation of a
pushed cuboid from MuJoCo's path (12 cm instead of 6 cm on the synthetic pushes), hence
the 2 ms step.

A step is about 60 kernel launches (drive targets, Steel's stages, the collision pipeline);
launched one by one from Python, packing their arguments took about 2.5 ms of a 3 ms step on
the CPU. The replay therefore records one step as a Warp graph (``wp.ScopedCapture``:
Warp 1.19's CPU graphs, which replay the recorded launches from C++, or a CUDA graph on a
GPU), two of them for the two ways round of the state swap, and launches a graph per step:
the same kernels on the same arrays, so the replay is bit for bit the one of per-kernel
launches (``simulate(..., capture=False)``), at about 0.4 ms a step on one CPU core (about
2 s of CPU time for an 8 s plan instead of 10 s). The drive targets of every step are
uploaded once; a one-thread kernel in the graph copies the current step's row and advances
a step counter on the device, and the host reads the state back only at the sampled frames.
Where graphs cannot be captured, each step launches its kernels itself.

Every value (the scene's, the drives', the solver's) comes from the scene description
``assets/robot_scene.toml`` that the MuJoCo replay reads too
(:func:`~warpskill.robot.scene_config.load_scene_config`).
"""

from __future__ import annotations

import functools
import re

import newton
import numpy as np
import warp as wp

from warpskill.contract.reconstruction import Reconstruction
from warpskill.robot.model import (
    ARM_JOINTS,
    FINGER_JOINTS,
    environment_boxes,
    make_scene,
    object_boxes,
    panda_urdf,
)
from warpskill.robot.plan import RobotPlan
from warpskill.robot.scene_config import load_scene_config
from warpskill.warp_log import configure_warp_log

configure_warp_log()  # before Newton builds anything: no "Module ... load on device" lines unless asked for

# Links standing on (or just above) the table: their contacts with the environment are not simulated
# (panda_link0 is merged into the world when the fixed joints are collapsed).
_BASE_LINKS = ("panda_link0", "panda_link1")
_FINGER_LINKS = ("panda_leftfinger", "panda_rightfinger")


def _transform(T: np.ndarray):
    """A Warp transform from a 4x4 pose."""
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
    """The finalized ``newton.Model`` of the plan's scene, robot drives set, and the indices the replay reads.

    Returns:
        ``(model, info)`` where ``info`` maps ``arm_coords``, ``finger_coords`` (``joint_q`` and
        ``joint_target_q`` indices), ``tcp_body``, ``object_body``, ``object_shapes``,
        ``finger_bodies``, ``robot_bodies``.
    """
    recon = plan.scene(recon)  # the cuboids as the plan handles them (sizes, poses: the object's start too)
    config = load_scene_config()
    panda, friction, gap = config.panda, config.contact.friction, config.newton.contact_gap
    builder = newton.ModelBuilder()
    builder.default_shape_cfg = newton.ModelBuilder.ShapeConfig(mu=friction, gap=gap)
    text = re.sub(r"<visual>.*?</visual>", "", panda_urdf(collision="meshes"), flags=re.S)
    text = re.sub(r"<mimic[^>]*/>", "", text)  # each finger has its own drive, as in MuJoCo
    builder.add_urdf(text, xform=_transform(plan.base), floating=False, enable_self_collisions=False,
                     collapse_fixed_joints=True)
    joints = [_label(builder.joint_label, name) for name in ARM_JOINTS + FINGER_JOINTS]
    coords = [builder.joint_q_start[j] for j in joints]
    dofs = [builder.joint_qd_start[j] for j in joints]
    q0 = np.concatenate([plan.q[0], [plan.gripper[0] / 2] * 2])
    ke = np.concatenate([panda.arm_kp, [panda.finger_kp] * 2])
    kd = np.concatenate([panda.arm_kv, [panda.finger_kv] * 2])
    effort = np.concatenate([panda.arm_torque_limit, [panda.grip_force] * 2])
    armature = [panda.arm_armature] * 7 + [0.0] * 2
    damping = [panda.arm_damping] * 7 + [panda.finger_damping] * 2
    for i, (coord, dof) in enumerate(zip(coords, dofs)):
        builder.joint_q[coord] = builder.joint_target_q[coord] = float(q0[i])
        builder.joint_target_mode[dof] = int(newton.JointTargetMode.POSITION)
        builder.joint_target_ke[dof] = float(ke[i])
        builder.joint_target_kd[dof] = float(kd[i])
        builder.joint_effort_limit[dof] = float(effort[i])
        builder.joint_armature[dof] = float(armature[i])
        builder.joint_damping[dof] = float(damping[i])
    robot_bodies = list(range(builder.body_count))
    bodies = builder.body_label
    base_bodies = {-1} | {i for i, label in enumerate(bodies) if label.rsplit("/", 1)[-1] in _BASE_LINKS}
    base_shapes = [s for s, b in enumerate(builder.shape_body) if b in base_bodies]

    scene = make_scene(recon, base=plan.base)
    env_cfg = newton.ModelBuilder.ShapeConfig(mu=friction, gap=gap)
    for name, T, size in environment_boxes(scene):
        hx, hy, hz = (float(v) for v in size / 2)
        shape = builder.add_shape_box(-1, xform=_transform(T), hx=hx, hy=hy, hz=hz, cfg=env_cfg, label=name)
        for other in base_shapes:
            builder.add_shape_collision_filter_pair(other, shape)
    T0 = np.eye(4)
    T0[:3, :3] = recon.object_rot[0]
    T0[:3, 3] = recon.object_pos[0]
    boxes = object_boxes(recon)
    volume = 8.0 * sum(float(np.prod(half)) for _, half in boxes)
    obj_cfg = newton.ModelBuilder.ShapeConfig(mu=friction, gap=gap, density=config.object.mass / volume)
    obj = builder.add_body(xform=_transform(T0), label="object")
    obj_shapes = []
    for i, (centre, half) in enumerate(boxes):
        hx, hy, hz = (float(v) for v in half)
        obj_shapes.append(builder.add_shape_box(obj, xform=wp.transform(wp.vec3(*centre), wp.quat_identity()), hx=hx,
                                                hy=hy, hz=hz, cfg=obj_cfg, label="object" if i == 0 else f"object{i}"))
    model = builder.finalize(device=device)
    info = {
        "arm_coords": coords[:7],
        "finger_coords": coords[7:],
        "tcp_body": _label(bodies, "panda_link7"),
        "robot_bodies": robot_bodies,
        "object_body": obj,
        "object_shapes": obj_shapes,
        "finger_bodies": sorted(_label(bodies, name) for name in _FINGER_LINKS),
    }
    return model, info


def simulate(plan: RobotPlan, recon: Reconstruction, times: np.ndarray, *, device: str | None = None,
             capture: bool | None = None) -> dict[str, np.ndarray]:
    """Run the plan; sample the TCP, the object and the finger contacts at plan ``times``.

    ``capture``: replay each step as a captured Warp graph (default: the scene description's
    ``newton.capture_graph``); False launches every kernel from Python (the same physics,
    several times slower on the CPU).

    Returns the arrays of :func:`warpskill.robot.replay_mujoco.simulate` (``q``: the simulated
    arm joints).
    """
    with wp.ScopedDevice(device):
        model, info = build_model(plan, recon)
        state_0, state_1 = model.state(), model.state()
        control = model.control()
        newton.eval_fk(model, model.joint_q, model.joint_qd, state_0)
        # The fixed joints are collapsed into panda_link7: the TCP's offset from it comes
        # from the planned TCP at the first sample (where the robot stands at plan.q[0]).
        tcp_offset = np.linalg.inv(_pose(state_0.body_q.numpy()[info["tcp_body"]])) @ plan.tcp[0]
        # Gravity compensation of the robot links; body_f is never cleared.
        robot = info["robot_bodies"]
        wrench = np.zeros((model.body_count, 6), dtype=np.float32)
        wrench[robot, :3] = -model.body_mass.numpy()[robot, None] * model.gravity.numpy()[0]
        for state in (state_0, state_1):
            state.body_f.assign(wrench)
        pipeline = newton.CollisionPipeline(model, reduce_contacts=False)
        contacts = pipeline.contacts()
        options = load_scene_config().newton
        solver = newton.solvers.SolverSteel(model, iterations=options.iterations,
                                            articulation_constraint_max=options.row_capacity,
                                            enable_joint_limits=True, joint_limit_activation_gap=options.limit_gap)
        # The drive targets of every step, uploaded once: a step copies its row on the device.
        timestep = options.timestep
        steps = int(np.ceil(times[-1] / timestep)) + 1
        t = np.arange(steps) * timestep
        targets = np.tile(model.joint_target_q.numpy(), (steps, 1))
        for i, coord in enumerate(info["arm_coords"]):
            targets[:, coord] = np.interp(t, plan.t, plan.q[:, i])
        targets[:, info["finger_coords"]] = np.interp(t, plan.t, plan.gripper)[:, None] / 2
        width = targets.shape[1]
        targets = wp.array(targets.reshape(-1), dtype=wp.float32)
        row = wp.zeros(1, dtype=wp.int32)  # the step whose targets the next step reads (advanced on the device)
        set_targets = _target_kernel()

        def advance(source, target) -> None:
            """One physics step ``source -> target``, then the contacts of ``target``."""
            wp.launch(set_targets, dim=1, inputs=[targets, row, width, steps], outputs=[control.joint_target_q])
            solver.step(source, target, control, contacts, timestep)
            pipeline.collide(target, contacts)

        pipeline.collide(state_0, contacts)
        use_graph = options.capture_graph if capture is None else capture
        graphs = _capture(advance, state_0, state_1) if use_graph else None
        finger_bodies = set(info["finger_bodies"])
        shape_body = model.shape_body.numpy()
        out = {"tcp": [], "object_pos": [], "object_rot": [], "held": [], "q": []}
        k = 0
        for step in range(steps):
            if times[k] <= t[step] + 1e-9:
                body_q, joint_q = state_0.body_q.numpy(), state_0.joint_q.numpy()
                touched = {int(shape_body[s]) for s in _touching(contacts, info["object_shapes"], body_q, shape_body)}
                P = _pose(body_q[info["object_body"]])
                while k < len(times) and times[k] <= t[step] + 1e-9:
                    out["tcp"].append(_pose(body_q[info["tcp_body"]]) @ tcp_offset)
                    out["object_pos"].append(P[:3, 3])
                    out["object_rot"].append(P[:3, :3])
                    out["held"].append(float(finger_bodies <= touched))
                    out["q"].append(joint_q[info["arm_coords"]].copy())
                    k += 1
                if k >= len(times):
                    break
            if graphs is not None:
                wp.capture_launch(graphs[step % 2])  # state_0 is the first state on even steps
            else:
                advance(state_0, state_1)
            state_0, state_1 = state_1, state_0
    return {key: np.asarray(value) for key, value in out.items()}


@functools.cache
def _target_kernel():
    """The Warp kernel that copies one step's drive targets and advances the step counter."""
    @wp.kernel
    def set_step_targets(targets: wp.array(dtype=wp.float32), row: wp.array(dtype=wp.int32), width: int,
                         rows: int, joint_target_q: wp.array(dtype=wp.float32)):
        start = wp.min(row[0], rows - 1) * width
        for j in range(width):
            joint_target_q[j] = targets[start + j]
        row[0] = row[0] + 1

    return set_step_targets


def _capture(advance, state_0, state_1):
    """Two captured graphs, ``advance(state_0, state_1)`` and ``advance(state_1, state_0)``, or None.

    Recording a graph runs nothing (on the CPU, Warp records the launches; on CUDA the
    stream is captured); replaying one launches its kernels from C++ (CPU) or as a CUDA
    graph, without Python's per-launch argument packing, about 60 launches a step. None
    where this Warp cannot capture on the device (the replay then launches each step's
    kernels itself).
    """
    graphs = []
    for source, target in ((state_0, state_1), (state_1, state_0)):
        try:
            with wp.ScopedCapture() as capture:
                advance(source, target)
        except (RuntimeError, NotImplementedError):  # no graph capture on this device / Warp
            return None
        graphs.append(capture.graph)
    return graphs


def _touching(contacts, shapes: list[int], body_q: np.ndarray, shape_body: np.ndarray, *,
              tolerance: float = 1e-3) -> set[int]:
    """Other shapes within ``tolerance`` [m] of one of ``shapes`` (or penetrating it)."""
    n = int(contacts.rigid_contact_count.numpy()[0])
    a = contacts.rigid_contact_shape0.numpy()[:n]
    b = contacts.rigid_contact_shape1.numpy()[:n]
    sel = np.flatnonzero(np.isin(a, shapes) | np.isin(b, shapes))
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
    return ({int(s) for s in a[close]} | {int(s) for s in b[close]}) - set(shapes)
