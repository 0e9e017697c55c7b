"""The end of a pick-up: an object still held after the contact signal ends is for the physics to decide."""

import dataclasses
import importlib

import numpy as np
import pytest
import torch

from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.hypotheses import PhysicsHypothesis, carried_start, chosen_simulation, read_evidence
from warpskill.optimizer.inputs import held_after_contact
from warpskill.optimizer.pipeline import optimize
from warpskill.optimizer.scene import SceneTrajectories
from warpskill.optimizer.stage_b import PhysicalRollout
from warpskill.synthetic import make_demonstration

optimize_module = importlib.import_module("warpskill.optimizer.pipeline")
N, H, W = 20, 30, 40


def _masks(hand_box, object_box):
    """(N, 2, H, W) masks from per-frame boxes (callables k -> (r0, r1, c0, c1) or None)."""
    masks = np.zeros((N, 2, H, W), dtype=np.float32)
    for k in range(N):
        for channel, box in enumerate((hand_box(k), object_box(k))):
            if box is not None:
                r0, r1, c0, c1 = box
                masks[k, channel, max(r0, 0) : max(r1, 0), c0:c1] = 1
    return masks


CONTACT = np.arange(N) < 12


def test_an_object_held_to_the_end_is_in_doubt_after_the_signal():
    held = _masks(lambda k: (0, 10, 18, 22), lambda k: (10, 16, 15, 25))
    assert held_after_contact(held, CONTACT).tolist() == [False] * 12 + [True] * 8


def test_a_hand_box_ending_just_above_an_object_brought_near_still_holds_it():
    # Brought toward the camera, the object hides the hand's tip: the hand's box ends a few
    # pixels above the object's (2 rows here, a fifth of the object's 15 px side counts as touching).
    near = _masks(lambda k: (0, 10, 18, 22), lambda k: (12, 20, 12, 28))
    assert held_after_contact(near, CONTACT).tolist() == [False] * 12 + [True] * 8
    apart = _masks(lambda k: (0, 10, 18, 22), lambda k: (10, 18, 12, 28) if k < 12 else (14, 22, 12, 28))
    assert not held_after_contact(apart, CONTACT).any()


def test_a_hand_that_lets_go_and_leaves_leaves_no_doubt():
    left = _masks(lambda k: (0, 10 if k < 15 else 4, 18, 22) if k < 15 else (0, 3, 30, 34), lambda k: (10, 16, 15, 25))
    assert not held_after_contact(left, CONTACT).any()
    no_contact = np.zeros(N, dtype=bool)
    assert not held_after_contact(left, no_contact).any()


def test_an_object_that_leaves_through_the_border_with_the_hand_is_in_doubt():
    rising = lambda k: (10 - 2 * max(k - 8, 0), 16 - 2 * max(k - 8, 0), 15, 25) if k < 16 else None  # noqa: E731
    out = _masks(lambda k: (0, max(10 - 2 * max(k - 8, 0), 1), 18, 22), rising)
    contact = np.arange(N) < 14
    assert held_after_contact(out, contact).tolist() == [False] * 14 + [True] * 6
    # Vanishing in the middle of the image is not leaving the view.
    vanish = _masks(lambda k: (0, 10, 18, 22), lambda k: (10, 16, 15, 25) if k < 15 else None)
    assert not held_after_contact(vanish, CONTACT).any()


def test_a_box_that_stops_a_pixel_short_of_the_border_still_leaves_the_view():
    # Brought down toward the camera, out of the bottom of the view: the last box drawn ends
    # ``short`` rows above the frame's last row.
    def leaving(short):
        bottom = H - short  # exclusive: the last row drawn is H - 1 - short
        sinking = lambda k: (10 + 2 * max(k - 8, 0), min(16 + 2 * max(k - 8, 0), bottom), 15, 25) if k < 16 else None  # noqa: E731
        return _masks(lambda k: (0, min(12 + 2 * max(k - 8, 0), bottom), 18, 22), sinking)

    contact = np.arange(N) < 14
    assert held_after_contact(leaving(1), contact).tolist() == [False] * 14 + [True] * 6
    assert not held_after_contact(leaving(5), contact).any()  # vanished inside the image


def test_a_small_held_object_is_read_at_the_masks_own_resolution():
    # A 4 x 4 px object held still at the hand's tip to the end: averaged down to the optimiser's
    # working resolution (a quarter) it straddles four pixels at a quarter each, and would seem
    # to vanish in the middle of the image; read as drawn, it is in doubt after the signal.
    demo = make_demonstration("pick_up", seed=0, image_size=(120, 160))
    n = demo.num_frames
    contact = np.arange(n) < n // 2
    hand = np.zeros((n, 120, 160), np.float32)
    hand[:, 20:62, 70:90] = 1
    small = np.zeros_like(hand)
    small[:, 62:66, 82:86] = 1
    held = dataclasses.replace(demo, hand_mask=hand, object_mask=small, contact=contact)
    evidence = read_evidence(held, {}, OptimizeConfig(image_scale=0.25), torch.device("cpu"))
    assert evidence.inputs.masks.shape[-2:] == (30, 40) and evidence.inputs.masks[:, 1].max() < 0.5
    assert evidence.held.tolist() == [False] * (n // 2) + [True] * (n - n // 2)


def test_an_object_that_moves_on_after_the_hand_box_ends_was_carried():
    # The hand's boxes stop with the signal; the object's box goes on rising: carried.
    rising = _masks(lambda k: (0, 10, 18, 22) if k < 12 else None,
                    lambda k: (10 - min(max(k - 11, 0), 6), 16 - min(max(k - 11, 0), 6), 15, 25))
    assert held_after_contact(rising, CONTACT).tolist() == [False] * 12 + [True] * 8
    # Standing still where the hand left it, even as its top comes out from under the hand: let go.
    uncovered = _masks(lambda k: (0, 10, 18, 22) if k < 12 else None, lambda k: (10 if k < 12 else 7, 16, 15, 25))
    assert not held_after_contact(uncovered, CONTACT).any()
    # A pixel of jitter at the bottom is no motion.
    jitter = _masks(lambda k: (0, 10, 18, 22) if k < 12 else None, lambda k: (10, 16 + k % 2, 15, 25))
    assert not held_after_contact(jitter, CONTACT).any()


def _lift(k):
    """An object box 3 rows high resting at rows 24-27, lifted 12 rows during the contact (frames 2-11)."""
    rise = min(max(k - 2, 0), 8) * 1.5
    return (int(24 - rise), int(27 - rise), 15, 25)


def test_an_object_lifted_and_left_hanging_where_the_hand_box_ends_is_in_doubt():
    # The hand's boxes stop with the signal; the object stays where it was lifted: a released
    # object would have fallen, so the physics decides.
    hanging = _masks(lambda k: (0, 14, 18, 22) if k < 12 else None, _lift)
    assert held_after_contact(hanging, CONTACT).tolist() == [False] * 12 + [True] * 8
    # Lifted, then set down again in the contact's last third: a put, not a hold.
    set_down = _masks(lambda k: (0, 14, 18, 22) if k < 12 else None,
                      lambda k: _lift(k) if k < 9 else (20, 23, 15, 25))
    assert not held_after_contact(set_down, CONTACT).any()
    # Raised by less than its own height (a push away from the camera): no lift.
    pushed = _masks(lambda k: (0, 14, 18, 22) if k < 12 else None,
                    lambda k: (24 - min(k, 2), 30 - min(k, 2), 15, 25))
    assert not held_after_contact(pushed, CONTACT).any()


def test_a_lift_beside_a_static_box_says_nothing_of_a_hold():
    # The static may hide the object's bottom: its box's rise is no lift.
    hanging = _masks(lambda k: (0, 14, 18, 22) if k < 12 else None, _lift)
    static = np.zeros((N, 1, H, W), dtype=np.float32)
    static[:, 0, 15:29, 26:38] = 1
    assert not held_after_contact(np.concatenate([hanging, static], 1), CONTACT).any()


def test_the_held_ending_starts_with_hand_and_object_together():
    n = 6
    object_pos = torch.tensor([[0.0, 0.5, 0.05]] * 3 + [[0.0, 0.4, 0.15], [0.0, 0.3, 0.2], [0.0, 0.25, 0.2]])
    hand_pos = torch.tensor([[0.0, 0.5, 0.1]] * 3 + [[0.3, 0.6, 0.4]] * 3)  # stage (a)'s free hand wanders off
    eye = torch.eye(3).expand(n, 3, 3)
    start = SceneTrajectories(hand_pos, eye, object_pos, eye, torch.full((3,), 0.05), torch.zeros(0, 3),
                              torch.zeros(0, 3, 3), torch.zeros(0, 3), torch.tensor(0.45), torch.tensor(0.5))
    signal = np.arange(n) < 3
    hand_seen = np.arange(n) < 4  # the hand's box ends one frame after the signal
    carried = carried_start(start, signal, np.ones(n, bool), hand_seen)
    offset = hand_pos[2] - object_pos[2]
    assert torch.allclose(carried.object_pos[3], hand_pos[3] - offset)  # with the hand where it is seen
    assert torch.allclose(carried.hand_pos[4:], object_pos[4:] + offset)  # the hand with the object where unseen
    assert torch.equal(carried.hand_pos[:4], hand_pos[:4]) and torch.equal(carried.object_pos[:3], object_pos[:3])
    assert torch.equal(carried.object_pos[4:], object_pos[4:])
    assert carried_start(start, signal, signal, hand_seen) is start  # the variant as given: unchanged


@pytest.mark.slow
def test_both_endings_go_through_the_physics_and_the_video_picks_one(monkeypatch):
    calls = []
    make = optimize_module.make_physical_scene

    def counted(fit, contact, *args, **kwargs):
        calls.append(np.asarray(contact).copy())
        return make(fit, contact, *args, **kwargs)

    monkeypatch.setattr(optimize_module, "make_physical_scene", counted)
    small = OptimizeConfig(iterations=4, init_iterations=4)
    demo = make_demonstration("pick_up", seed=0, input="boxes", image_size=(60, 107), duration=2.0)
    recon = optimize(demo, config=small, progress=False)
    assert len(calls) == 2 and calls[1].sum() > calls[0].sum() and calls[1][-1]
    assert recon.num_frames == demo.num_frames
    calls.clear()
    optimize(make_demonstration("put_onto", seed=0, image_size=(60, 107), duration=2.0), config=small,
             progress=False)
    assert len(calls) == 1


def _ending_at(start: SceneTrajectories, height: float) -> SceneTrajectories:
    """``start`` with the object's last centre at ``height`` [m] (upright)."""
    object_pos = start.object_pos.clone()
    object_pos[-1, 2] = height
    return dataclasses.replace(start, object_pos=object_pos)


def _resting_under_the_hand(n: int, hand_height: float = 0.07) -> SceneTrajectories:
    """A 6 cm cube on the ground at y = 0.5 m with the hand's tip above it at ``hand_height`` [m]."""
    eye = torch.eye(3).expand(n, 3, 3)
    return SceneTrajectories(torch.tensor([[0.0, 0.5, hand_height]]).repeat(n, 1), eye,
                             torch.tensor([[0.0, 0.5, 0.03]]).repeat(n, 1), eye, torch.full((3,), 0.06),
                             torch.zeros(0, 3), torch.zeros(0, 3, 3), torch.zeros(0, 3), torch.tensor(0.45),
                             torch.tensor(0.5))


def test_a_release_that_drops_what_stage_a_leaves_in_the_air_is_ruled_out():
    # A box pick-up's action phase ends while the hand still holds the object: both endings are tried.
    demo = make_demonstration("pick_up", seed=0, input="boxes", image_size=(60, 107), duration=2.0)
    seen = read_evidence(demo, {}, OptimizeConfig(), torch.device("cpu"))
    given = seen.inputs.contact_signal
    assert seen.held.any()
    n = demo.num_frames
    scene = _resting_under_the_hand(n)
    on_ground, up = _ending_at(scene, 0.03), _ending_at(scene, 0.2)  # the object's bottom 0 or 17 cm up

    def choice(stage_a_end: SceneTrajectories, released_fit: float) -> str:
        own = [PhysicsHypothesis(0, stage_a_end, given, None, None, fit=released_fit),
               PhysicsHypothesis(0, stage_a_end, given | seen.held, None, None, fit=1.0)]
        results = [PhysicalRollout(on_ground, None, None, None), PhysicalRollout(up, None, None, None)]
        return ["released", "held"][chosen_simulation(seen, own, results)]

    # Stage (a) leaves the object 17 cm up at the end: dropping it contradicts the masks, however well it fits.
    assert choice(up, released_fit=0.5) == "held"
    # Stage (a) sets it down: the better fit decides.
    assert choice(on_ground, released_fit=0.5) == "released"
    assert choice(on_ground, released_fit=1.5) == "held"


def test_a_release_whose_hand_hovers_off_the_object_it_is_seen_on_is_ruled_out():
    # After the signal the masks show the hand on the object to the end. A release that keeps
    # the hand's tip 15 cm off the object (along the camera's rays) contradicts them, however
    # well it fits; one whose hand stays 2 cm off is for the fit to decide.
    demo = make_demonstration("pick_up", seed=0, input="boxes", image_size=(60, 107), duration=2.0)
    seen = read_evidence(demo, {}, OptimizeConfig(), torch.device("cpu"))
    given, n = seen.inputs.contact_signal, demo.num_frames
    assert (seen.held & seen.hand_seen).any()

    def choice(hand_height: float) -> str:
        released, held = _resting_under_the_hand(n, hand_height), _resting_under_the_hand(n)
        own = [PhysicsHypothesis(0, released, given, None, None, fit=0.5),
               PhysicsHypothesis(0, held, given | seen.held, None, None, fit=1.0)]
        results = [PhysicalRollout(released, None, None, None), PhysicalRollout(held, None, None, None)]
        return ["released", "held"][chosen_simulation(seen, own, results)]

    assert choice(hand_height=0.06 + 0.15) == "held"
    assert choice(hand_height=0.06 + 0.02) == "released"
