"""An object nobody has touched yet does not move: the robot grasps it where the hand first touches it."""

from __future__ import annotations

import dataclasses

import numpy as np
from robot_support import require_robot

robot = require_robot("placo", "mujoco")

from warpskill.contract import Reconstruction  # noqa: E402
from warpskill.robot.replaying import replay  # noqa: E402
from warpskill.robot.sizes import fit_sizes  # noqa: E402
from warpskill.synthetic import make_demonstration  # noqa: E402

DRIFT = np.array([0.06, 0.03, 0.0])  # [m] how far the untouched object slides before the grasp onset


def drifting_pick_up() -> tuple[Reconstruction, int]:
    """The pick-up's ground truth with the object sliding :data:`DRIFT` into place before the onset
    (a reconstruction's artefact: the object seen moving before the hand reaches it), and the onset."""
    recon = Reconstruction(**make_demonstration("pick_up", seed=0, noise="none").truth)
    onset = int(np.flatnonzero(recon.grasped > 0.5)[0])
    object_pos = recon.object_pos.copy()
    object_pos[:onset] += np.linspace(1.0, 0.0, onset, endpoint=False)[:, None] * DRIFT
    return dataclasses.replace(recon, object_pos=object_pos), onset


def test_the_object_rests_at_its_onset_place_until_touched():
    recon, onset = drifting_pick_up()
    fitted, _ = fit_sizes(recon)
    assert np.allclose(fitted.object_pos[:onset, :2], fitted.object_pos[onset, :2])
    assert np.allclose(fitted.object_pos[:, 2], recon.object_pos[:, 2])  # heights (settling) kept
    assert np.allclose(fitted.object_pos[onset:], recon.object_pos[onset:])


def test_a_drifting_object_is_still_picked_up():
    recon, _ = drifting_pick_up()
    plan = robot.retarget(recon)
    result = replay(plan, recon, engine="mujoco")
    assert result.success, result.evaluation.checks
