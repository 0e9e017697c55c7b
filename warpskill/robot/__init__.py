"""Robot re-targeting: a Franka Panda performs the reconstructed manipulation (issue 5).

- :func:`retarget`: reconstruction -> :class:`RobotPlan` (placo differential IK).
- :func:`replay`: simulate a plan in MuJoCo or Newton -> :class:`Replay` (the simulated
  object and gripper as a reconstruction, and whether the action succeeded).

Needs the optional packages ``placo``, ``mujoco``, ``example-robot-data`` (and ``newton``
for that engine); they are imported on first use.
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "retarget": "retargeting",
    "RobotPlan": "plan",
    "PlanError": "plan",
    "Placement": "model",
    "replay": "replaying",
    "Replay": "replaying",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module 'warpskill.robot' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    globals()[name] = value
    return value
