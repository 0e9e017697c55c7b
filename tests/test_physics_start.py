"""Where the physics stage starts: the hand must be in the object when the contact begins."""

import numpy as np
import pytest
import torch

from warpskill.engine.simulation import substeps_per_frame
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.physical_start import (
    START_CLEARANCE,
    SplineTiming,
    grasp_window,
    isolated_misfit_weights,
    physical_start,
)
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


def _fit_from_above(gap: float) -> SceneTrajectories:
    """Stage (a)'s per-frame scene: the cube of :func:`_fit` drifting 6 cm, and a hand coming
    straight down over the cube's first place, whose tip stops ``gap`` [m] above its top at the
    onset."""
    fit = _fit(0.06)
    t = torch.arange(N, dtype=torch.float32)
    tip_z = SIZE + gap + 0.02 * (ONSET - t).clamp(min=0.0)
    fit.hand_pos = torch.stack([torch.zeros_like(t), torch.full_like(t, 0.4), tip_z], 1)
    return fit


def test_a_resting_object_is_not_lifted_to_meet_a_hand_above_it():
    fit = _fit_from_above(0.03)
    scene = make_physical_scene(fit, CONTACT, FPS, OptimizeConfig())
    # Raised to the tip, the cube would float and fall before the hand arrives: it stays on
    # the ground, and the hand path moves down by its most (2 cm).
    assert torch.equal(scene.object_pos0.detach(), fit.object_pos[0])
    assert float(fit.hand_pos[0, 2] - scene.hand_pos0.detach()[2]) == pytest.approx(0.02, abs=1e-6)


def test_an_object_carried_into_view_starts_where_the_hand_above_it_takes_it():
    fit = _fit_from_above(0.03)
    scene = make_physical_scene(fit, CONTACT, FPS, OptimizeConfig(), unseen_before_contact=True)
    # Nothing says it rested: it starts in the hand, more than the 3 cm - 2 cm higher.
    assert float(scene.object_pos0.detach()[2] - fit.object_pos[0, 2]) > 0.01


def _sliding_hand(frames: int, bump: slice, height: float) -> SceneTrajectories:
    """Stage (a)'s per-frame scene: a hand sliding along +x at 10 cm/s, 10 cm above the
    ground, that stage (a) put ``height`` [m] higher in the ``bump`` frames; a cube far away."""
    t = torch.arange(frames, dtype=torch.float32)
    hand_pos = torch.stack([0.1 * t / FPS, torch.full_like(t, 0.4), torch.full_like(t, 0.1)], 1)
    hand_pos[bump, 2] += height
    eye = torch.eye(3)
    return SceneTrajectories(
        hand_pos=hand_pos, hand_rot=eye.expand(frames, 3, 3).clone(),
        object_pos=torch.tensor([0.5, 0.4, SIZE / 2]).expand(frames, 3).clone(),
        object_rot=eye.expand(frames, 3, 3).clone(), object_size=torch.full((3,), SIZE),
        static_pos=torch.zeros(0, 3), static_rot=torch.zeros(0, 3, 3), static_size=torch.zeros(0, 3),
        camera_height=torch.tensor(0.45), camera_elevation=torch.tensor(0.6),
    )


def test_the_hand_spline_starts_past_frames_whose_hand_stage_a_could_not_match():
    frames, bump = 36, slice(17, 19)
    fit = _sliding_hand(frames, bump, 0.15)
    hand_loss = np.full(frames, 0.2)
    hand_loss[bump] = 0.9  # those two frames' hand masks were not matched

    def start_height_error(loss) -> float:
        scene = make_physical_scene(fit, np.zeros(frames, dtype=bool), FPS, OptimizeConfig(), hand_loss=loss)
        with torch.no_grad():
            return float((scene().rollout.hand_pos[:, 2] - 0.1).abs().max())

    assert start_height_error(None) > 0.05  # fitted alike, the misplaced frames raise the spline
    assert start_height_error(hand_loss) < 0.005


def test_only_isolated_misfits_lose_weight():
    spike = np.full(30, 0.2)
    spike[12:14] = 0.9
    weights = isolated_misfit_weights(spike)
    assert weights[12:14].max() < 1e-3
    assert np.delete(weights, [12, 13]).min() == 1.0
    # A long stretch fitted worse (a cylinder against a real hand's box) is the norm, not a misfit.
    stretch = np.where(np.arange(30) < 10, 0.2, 0.6)
    assert isolated_misfit_weights(stretch).min() > 0.99


def test_misfit_weights_refuse_missing_or_misaligned_losses():
    with pytest.raises(ValueError, match="hand_loss"):
        isolated_misfit_weights(np.array([0.1, np.nan, 0.2]))
    with pytest.raises(ValueError, match=r"hand_loss must be \(16,\)"):
        make_physical_scene(_fit(0.0), CONTACT, FPS, OptimizeConfig(), hand_loss=np.zeros(N - 1))


def test_an_object_stage_a_left_in_a_static_box_starts_clear_and_stays_there():
    fit = _fit(0.0)  # the cube rests at y = 0.4; a 30 x 20 x 10 cm box reaches 1.5 cm into its back
    fit.static_pos = torch.tensor([[0.0, 0.4 + SIZE / 2 + 0.1 - 0.015, 0.05]])
    fit.static_rot, fit.static_size = torch.eye(3)[None], torch.tensor([[0.3, 0.2, 0.1]])
    scene = make_physical_scene(fit, np.zeros(N, dtype=bool), FPS, OptimizeConfig())
    start = scene.object_pos0.detach()
    assert float(fit.object_pos[0, 1] - start[1]) == pytest.approx(0.015 + START_CLEARANCE, abs=1e-6)  # out the front
    with torch.no_grad():
        moved = scene().rollout.object_pos[:, :2] - start[:2]
    assert float(moved.norm(dim=-1).max()) < 0.002  # not knocked away by the box


def test_the_grasp_signal_is_open_by_the_first_contact_frame():
    """The spline cannot step: fitted to the contact alone, the grasp signal would cross zero
    at the onset and hold the switch half open there, while the tip enters. Its target opens
    half a knot interval early, so at the onset it is near its full level."""
    scene = make_physical_scene(_fit(0.0), CONTACT, FPS, OptimizeConfig())
    with torch.no_grad():
        grasp = scene().rollout.grasp
    level = 2.0 * OptimizeConfig().weights.grasp_margin
    assert float(grasp[ONSET]) > 0.75 * level
    assert float(grasp[ONSET - 4]) < 0.0  # still shut well before


def test_the_grasp_window_opens_a_few_frames_before_each_contact():
    contact = np.array([0, 0, 0, 0, 1, 1, 0, 0, 1, 0], dtype=bool)
    assert grasp_window(contact, 2).astype(int).tolist() == [0, 0, 1, 1, 1, 1, 1, 1, 1, 0]
    assert grasp_window(np.ones(3, dtype=bool), 2).all() and not grasp_window(np.zeros(3, dtype=bool), 2).any()


def test_the_start_is_computed_from_the_fit_and_leaves_it_as_it_was():
    fit = _fit(0.06)
    before = {name: value.clone() for name, value in vars(fit).items() if isinstance(value, torch.Tensor)}
    config = OptimizeConfig()
    timing = SplineTiming.of(N, FPS, substeps_per_frame(FPS, config.physics), config.knots_per_second)
    start = physical_start(fit, CONTACT, timing, knots_per_second=config.knots_per_second,
                           grasp_level=2.0 * config.weights.grasp_margin)
    assert all(torch.equal(getattr(fit, name), value) for name, value in before.items())
    assert start.control.shape == (timing.num_knots, 7)
    # The object moved to where the hand takes it (the drift), the scene registers exactly that start.
    assert float(start.object_pos0[0] - fit.object_pos[0, 0]) > 0.0
    scene = make_physical_scene(fit, CONTACT, FPS, config)
    for name in ("hand_rot6", "grasp0", "control", "hand_pos0", "object_pos0", "object_rot6"):
        assert torch.equal(getattr(scene, name).detach(), getattr(start, name)), name
