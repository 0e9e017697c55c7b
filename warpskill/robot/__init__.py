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

__all__, __getattr__, __dir__ = lazy_exports(__name__, globals(), {
    "retargeting": ("retarget", "robot_reconstruction"),
    "skill_layout": ("skill_from", "apply_skill", "demonstrated_layout"),
    "plan": ("RobotPlan", "PlanError"),
    "model": ("Placement", "make_scene"),
    "placement": ("rank_placements", "check_reach"),
    "sizes": ("fit_sizes",),
    "replaying": ("replay", "Replay"),
    "video": ("prefer_headless_gl", "record"),
    "kinematics": ("link_poses", "link_shapes", "LinkShape"),
    "track": ("RobotTrack", "robot_track"),
})
