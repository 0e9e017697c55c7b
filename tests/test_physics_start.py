"""Where the physics stage starts: the hand must be in the object when the contact begins."""

import numpy as np
import pytest
import torch

from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.scene import SceneTrajectories
from warpskill.optimizer.stage_b import make_physical_scene

N, FPS, ONSET = 16, 12.0, 8
SIZE = 0.08  # [m] cube edge
CONTACT = np.arange(N) >= ONSET


def _fit(drift: float) -> SceneTrajectories:
    """Stage (a)'s per-frame scene: a cube on the ground that slides ``drift`` [m] along +x
    before the contact (stage (a) asks an untouched object to rest, weakly), and a hand
    coming from +x whose tip is 1 cm inside the drifted cube from the onset on."""
    t = torch.arange(N, dtype=torch.float32)
    object_x = drift * (t / ONSET).clamp(max=1.0)
    object_pos = torch.stack([object_x, torch.full_like(t, 0.4), torch.full_like(t, SIZE / 2)], 1)
    tip_x = object_x + SIZE / 2 - 0.01 + 0.02 * (ONSET - t).clamp(min=0.0)  # arrives at the onset
    hand_pos = torch.stack([tip_x, torch.full_like(t, 0.4), torch.full_like(t, SIZE / 2)], 1)
    eye = torch.eye(3)
    return SceneTrajectories(
        hand_pos=hand_pos, hand_rot=eye.expand(N, 3, 3).clone(), object_pos=object_pos,
        object_rot=eye.expand(N, 3, 3).clone(), object_size=torch.full((3,), SIZE),
        static_pos=torch.zeros(0, 3), static_rot=torch.zeros(0, 3, 3), static_size=torch.zeros(0, 3),
        camera_height=torch.tensor(0.45), camera_elevation=torch.tensor(0.6),
    )


def _tip_distance_at_onset(scene) -> float:
    with torch.no_grad():
        return float(scene().rollout.tip_distance[ONSET])


@pytest.mark.parametrize("drift", [0.03, 0.06])
def test_an_object_that_stage_a_let_drift_before_the_grasp_starts_where_the_hand_takes_it(drift):
    fit = _fit(drift)
    scene = make_physical_scene(fit, CONTACT, FPS, OptimizeConfig())
    # The hand path moves by at most 2 cm; the object makes up the rest, up to its drift.
    moved = float(scene.object_pos0.detach()[0] - fit.object_pos[0, 0])
    assert 0.0 < moved <= drift + 1e-6
    assert _tip_distance_at_onset(scene) < 0.0  # the tip is inside: the grasp can close


def test_an_object_that_stage_a_kept_still_stays_where_it_is():
    fit = _fit(0.0)
    scene = make_physical_scene(fit, CONTACT, FPS, OptimizeConfig())
    assert torch.equal(scene.object_pos0.detach(), fit.object_pos[0])
