"""Robot re-targeting: a Franka Panda performs the reconstructed manipulation (issue 5).

- :func:`retarget`: reconstruction -> :class:`RobotPlan` (placo differential IK).
- :func:`replay`: simulate a plan in MuJoCo or Newton -> :class:`Replay` (the simulated
  object and gripper as a reconstruction, and whether the action succeeded).

Needs the optional packages ``placo``, ``mujoco``, ``example-robot-data`` (and ``newton``
for that engine); they are imported on first use.
"""

from __future__ import annotations

from warpskill.lazy import lazy_exports

_EXPORTS = {
    "retarget": "retargeting",
    "RobotPlan": "plan",
    "PlanError": "plan",
    "Placement": "model",
    "replay": "replaying",
    "Replay": "replaying",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
