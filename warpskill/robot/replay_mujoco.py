"""Replaying a robot plan in MuJoCo: Panda (collision meshes), table and cuboids, position control.

The arm joints track the plan's joint positions (interpolated linearly at every physics
step) with stiff position actuators and gravity compensation; each finger has a position
actuator whose force is capped (``panda.grip_force``), so a closed command squeezes the
object. The manipulated cuboid is a free body (:data:`OBJECT_BODY`) of ``object.mass`` and
``contact.friction`` (an open vessel's: its bottom and walls, :func:`~warpskill.robot.model.object_boxes`); the table and static cuboids are fixed boxes. Every value (and the
video's lights and colours, which change no physics) comes from the scene description
``assets/robot_scene.toml`` (:func:`~warpskill.robot.scene_config.load_scene_config`).
"""

from __future__ import annotations

import numpy as np

from warpskill.contract.reconstruction import Reconstruction
from warpskill.robot.model import (
    ARM_JOINTS,
    FINGER_JOINTS,
    TCP_FRAME,
    environment_boxes,
    make_scene,
    mujoco_urdf,
    object_boxes,
)
from warpskill.robot.plan import RobotPlan
from warpskill.robot.scene_config import load_scene_config

OBJECT_BODY = "object"
"""Name of the manipulated cuboid's body (and of its first box geom) in the model."""

OBJECT_JOINT = "object_free"
"""Name of the manipulated cuboid's free joint in the model."""


def mujoco_quaternion(R: np.ndarray) -> np.ndarray:
    """(4,) MuJoCo's unit quaternion (w, x, y, z) of the rotation matrix ``R`` (3, 3)."""
    import mujoco  # optional extra: robot (imported after prefer_headless_gl picks its GL)

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=np.float64).reshape(9))
    return q


def build_model(plan: RobotPlan, recon: Reconstruction):
    """The compiled ``mujoco.MjModel`` of the plan's scene (robot base at ``plan.base``).

    The cuboids are those the plan handles (:meth:`RobotPlan.scene`: sizes, poses, the
    object's start and the plan's layout).
    """
    return build_spec(plan.scene(recon), plan.base).compile()


def build_spec(recon: Reconstruction, base_pose: np.ndarray):
    """The ``mujoco.MjSpec`` of the scene: the Panda (base at ``base_pose`` (4, 4)), the table,
    the static boxes and the object (a free body at its first-frame pose).

    Its options, contacts, drives and colours, and the video's lights, backdrop and
    offscreen frame size, are those of :func:`~warpskill.robot.scene_config.load_scene_config`.
    """
    import mujoco  # optional extra: robot (imported after prefer_headless_gl picks its GL)

    config = load_scene_config()
    panda, contact = config.panda, config.contact
    spec = mujoco.MjSpec.from_string(mujoco_urdf())
    spec.option.timestep = config.mujoco.timestep
    spec.option.cone = getattr(mujoco.mjtCone, "mjCONE_" + config.mujoco.cone.upper())
    spec.option.impratio = config.mujoco.impratio
    spec.option.integrator = getattr(mujoco.mjtIntegrator, "mjINT_" + config.mujoco.integrator.upper())
    base = spec.body("panda_link0")
    base.pos = base_pose[:3, 3]
    base.quat = mujoco_quaternion(base_pose[:3, :3])
    for body in spec.bodies:
        if body.name.startswith("panda_"):
            body.gravcomp = 1.0 if panda.gravity_compensation else 0.0
    for geom in spec.geoms:  # robot geoms touch the scene, not each other (the plan avoids self-collision)
        geom.friction = contact.mujoco_friction
        geom.condim = contact.condim
        geom.contype, geom.conaffinity = 2, 1
        geom.rgba = panda.rgba
    for name in ARM_JOINTS:
        joint = spec.joint(name)
        joint.armature = panda.arm_armature
        joint.damping = [panda.arm_damping, 0.0, 0.0]
    for name in FINGER_JOINTS:
        spec.joint(name).damping = [panda.finger_damping, 0.0, 0.0]
    world = spec.worldbody
    scene = make_scene(recon, base=base_pose)
    for name, T, size in environment_boxes(scene):
        world.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=size / 2, pos=T[:3, 3],
                       quat=mujoco_quaternion(T[:3, :3]),
                       friction=contact.mujoco_friction, condim=contact.condim, contype=1, conaffinity=3,
                       rgba=config.table.rgba if name == "table" else config.static.rgba)
    obj = world.add_body(name=OBJECT_BODY, pos=recon.object_pos[0], quat=mujoco_quaternion(recon.object_rot[0]))
    obj.add_freejoint(name=OBJECT_JOINT)
    boxes = object_boxes(recon)
    volume = sum(float(np.prod(half)) for _, half in boxes)
    for i, (centre, half) in enumerate(boxes):
        obj.add_geom(name=OBJECT_BODY if i == 0 else f"{OBJECT_BODY}{i}", type=mujoco.mjtGeom.mjGEOM_BOX, pos=centre,
                     size=half, mass=config.object.mass * float(np.prod(half)) / volume,
                     friction=contact.mujoco_friction, condim=contact.condim, contype=1, conaffinity=3,
                     solref=[config.mujoco.object_contact_timeconst, 1.0], priority=1, rgba=config.object.rgba)
    spec.add_exclude(bodyname1="panda_link0", bodyname2="world")
    spec.add_exclude(bodyname1="panda_link1", bodyname2="world")
    kv = panda.arm_kv
    for i, name in enumerate(ARM_JOINTS):
        _position_actuator(spec, name, panda.arm_kp[i], kv[i], panda.arm_torque_limit[i])
    for name in FINGER_JOINTS:
        _position_actuator(spec, name, panda.finger_kp, panda.finger_kv, panda.grip_force)
    _add_visuals(spec, config.video)
    return spec


def _add_visuals(spec, video) -> None:
    """The video's lights, backdrop and offscreen frame size (no effect on the physics)."""
    import mujoco  # optional extra: robot (imported after prefer_headless_gl picks its GL)

    for k, light in enumerate(video.lights):
        spec.worldbody.add_light(name=f"light{k}", type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                                 pos=-2.0 * np.asarray(light.direction), dir=light.direction,
                                 diffuse=light.diffuse, specular=light.specular, castshadow=light.castshadow)
    spec.add_texture(name="backdrop", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=video.background, rgb2=[1.0, 1.0, 1.0],
                     width=256, height=1536)
    headlight = spec.visual.headlight
    headlight.ambient, headlight.diffuse, headlight.specular = (video.headlight.ambient, video.headlight.diffuse,
                                                                 video.headlight.specular)
    spec.visual.global_.offwidth = max(spec.visual.global_.offwidth, video.width)
    spec.visual.global_.offheight = max(spec.visual.global_.offheight, video.height)


def _position_actuator(spec, joint: str, kp: float, kv: float, force: float) -> None:
    import mujoco  # optional extra: robot (imported after prefer_headless_gl picks its GL)

    act = spec.add_actuator(name=joint, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
    act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
    gain = np.zeros(10)
    gain[0] = kp
    bias = np.zeros(10)
    bias[1], bias[2] = -kp, -kv
    act.gainprm = gain
    act.biasprm = bias
    act.forcelimited = 1
    act.forcerange = [-force, force]


def simulate(plan: RobotPlan, recon: Reconstruction, times: np.ndarray, *, video=None,
             edit_model=None) -> dict[str, np.ndarray]:
    """Run the plan; sample the TCP, the object and the finger contacts at plan ``times``.

    ``edit_model(model)``, where given, changes the built ``mujoco.MjModel`` in place before
    the run (a perturbed mass, friction or object start); the model's derived constants
    (``mj_setConst``: the inverse weights that scale every contact's softness, the subtree
    masses) are then recomputed, so that a heavier object is not simulated with the contact
    softness of the lighter one (which lets it sink through the table and the run blow up).

    Returns:
        ``tcp`` (F, 4, 4), ``object_pos`` (F, 3), ``object_rot`` (F, 3, 3), ``held`` (F,) 1
        where both fingers touch the object, ``q`` (F, 7) simulated arm joints.
    """
    import mujoco  # optional extra: robot (imported after prefer_headless_gl picks its GL)

    model = build_model(plan, recon)
    if edit_model is not None:
        edit_model(model)
        mujoco.mj_setConst(model, mujoco.MjData(model))
    data = mujoco.MjData(model)
    arm_qpos = [model.joint(name).qposadr[0] for name in ARM_JOINTS]
    finger_qpos = [model.joint(name).qposadr[0] for name in FINGER_JOINTS]
    data.qpos[arm_qpos] = plan.q[0]
    data.qpos[finger_qpos] = plan.gripper[0] / 2
    mujoco.mj_forward(model, data)
    tcp_body = model.body(TCP_FRAME).id
    obj_body = model.body(OBJECT_BODY).id
    obj_geoms = set(np.flatnonzero(model.geom_bodyid == obj_body).tolist())
    finger_bodies = {model.body("panda_leftfinger").id, model.body("panda_rightfinger").id}
    timestep = model.opt.timestep
    steps = int(np.ceil(times[-1] / timestep)) + 1
    out = {"tcp": [], "object_pos": [], "object_rot": [], "held": [], "q": []}
    k = 0
    renderer = video.start(model) if video is not None else None
    for step in range(steps):
        t = step * timestep
        while k < len(times) and times[k] <= t + 1e-9:
            T = np.eye(4)
            T[:3, :3] = data.xmat[tcp_body].reshape(3, 3)
            T[:3, 3] = data.xpos[tcp_body]
            out["tcp"].append(T)
            out["object_pos"].append(data.xpos[obj_body].copy())
            out["object_rot"].append(data.xmat[obj_body].reshape(3, 3).copy())
            touching = set()
            for c in data.contact[: data.ncon]:
                if c.geom1 in obj_geoms or c.geom2 in obj_geoms:
                    touching.add(int(model.geom_bodyid[c.geom2 if c.geom1 in obj_geoms else c.geom1]))
            out["held"].append(float(finger_bodies <= touching))
            out["q"].append(data.qpos[arm_qpos].copy())
            if renderer is not None:
                video.frame(model, data)
            k += 1
        if k >= len(times):
            break
        q = np.array([np.interp(t, plan.t, plan.q[:, i]) for i in range(7)])
        g = float(np.interp(t, plan.t, plan.gripper))
        data.ctrl[:7] = q
        data.ctrl[7:9] = g / 2
        mujoco.mj_step(model, data)
    return {key: np.asarray(value) for key, value in out.items()}
