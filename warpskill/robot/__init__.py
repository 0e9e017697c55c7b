"""The robot: a Franka Panda performs the reconstructed manipulation.

Owns the Panda model and its scene, the grasp poses, retargeting (placo) and the MuJoCo and
Newton replays. May import :mod:`warpskill.contract` (it depends on the reconstruction file,
never on the optimiser's or the engine's internals) and the media leaf
(:mod:`warpskill.media`: video writers, the palette), never :mod:`warpskill.visual`; placo, MuJoCo and Newton are optional (extra ``robot``) and imported on first use.

- :func:`retarget`: reconstruction -> :class:`RobotPlan` (placo differential IK).
- :func:`replay`: simulate a plan in MuJoCo or Newton -> :class:`Replay` (the simulated
  object and gripper as a reconstruction, and whether the action succeeded); the perturbations
  a plan is robust to (:mod:`~warpskill.robot.perturbation`), applied to the MuJoCo model of a replay.

Needs the optional packages ``placo``, ``mujoco``, ``example-robot-data`` (and ``newton``
for that engine); they are imported on first use.
"""

from __future__ import annotations

from warpskill.lazy import lazy_exports

_EXPORTS = {
    "retarget": "retargeting",
    "skill_from": "skill_layout",
    "apply_skill": "skill_layout",
    "demonstrated_layout": "skill_layout",
    "robot_reconstruction": "retargeting",
    "RobotPlan": "plan",
    "PlanError": "plan",
    "Placement": "model",
    "make_scene": "model",
    "rank_placements": "placement",
    "check_reach": "placement",
    "fit_sizes": "sizes",
    "replay": "replaying",
    "Replay": "replaying",
    "prefer_headless_gl": "video",
    "record": "video",
    "link_poses": "kinematics",
    "link_shapes": "kinematics",
    "RobotTrack": "track",
    "robot_track": "track",
    "LinkShape": "kinematics",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
