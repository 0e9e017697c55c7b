"""What the robot tests need: skip a whole test module where the robot extra is missing."""

from __future__ import annotations

from types import ModuleType

import pytest


def require_robot(*packages: str) -> ModuleType:
    """Skip the calling test module unless ``packages`` (e.g. placo, mujoco), ``warpskill.robot``
    and the Panda's description are there; return ``warpskill.robot``."""
    for package in packages:
        pytest.importorskip(package)
    robot = pytest.importorskip("warpskill.robot")
    from warpskill.robot.model import RobotModelError, panda_description_dir

    try:
        panda_description_dir()
    except RobotModelError as error:  # pragma: no cover - depends on the environment
        pytest.skip(str(error), allow_module_level=True)
    return robot
