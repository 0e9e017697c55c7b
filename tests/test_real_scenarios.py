"""The real videos' annotation situations: each spoiler does what it says; the mix goes through the reader."""

import numpy as np
import pytest

from warpskill.contract.actions import ACTIONS
from warpskill.data.boxes.something_else import something_else_demonstration
from warpskill.synthetic import make_demonstration, real_scenarios
from warpskill.synthetic.scripts import ASKEW_OBJECT_YAW, NARROW_STATIC, TALL_THIN, TURNED_STATIC_YAW, Variant
from warpskill.synthetic.spoil import (
    as_annotations,
    enters_view,
    hand_partly_seen,
    static_cut_by_frame,
    stops_early,
)

N, H, W = 48, 60, 107


def _scene(rng=None):
    """Boxes (3, N, 4) of a hand, an object and a static object, all seen in every frame, and an action phase."""
    rng = rng or np.random.default_rng(0)
    x = np.linspace(10, 60, N)[:, None]
    hand = np.concatenate([x, x * 0 + 5, x + 20, x * 0 + 30], 1)
    obj = np.concatenate([x + 5, x * 0 + 30, x + 15, x * 0 + 40], 1)
    static = np.tile([[40.0, 25.0, 60.0, 45.0]], (N, 1)) + rng.uniform(-1, 1, (N, 4))
    contact = np.zeros(N, bool)
    contact[16:30] = True
    return np.stack([hand, obj, static]), contact


def _seen(boxes):
    return ~np.isnan(boxes[..., 0])


@pytest.mark.parametrize("seed", range(5))
def test_stops_early_removes_every_box_of_the_last_9_to_21_frames_and_ends_the_action_phase_there(seed):
    boxes, contact = _scene()
    spoilt, phase = stops_early(boxes, contact, np.random.default_rng(seed), (H, W))
    last = np.flatnonzero(_seen(spoilt).any(0))[-1]
    assert 9 <= N - 1 - last <= 21
    assert not _seen(spoilt[:, last + 1 :]).any() and _seen(spoilt[:, : last + 1]).all()
    assert np.flatnonzero(phase)[-1] == last and np.flatnonzero(phase)[0] == 16


def test_enters_view_hides_the_object_until_about_the_action_phase():
    boxes, contact = _scene()
    for seed in range(10):
        spoilt, phase = enters_view(boxes, contact, np.random.default_rng(seed), (H, W))
        first = np.flatnonzero(_seen(spoilt[1]))[0]
        assert 14 <= first <= 19
        assert _seen(spoilt[1, first:]).all() and (phase == contact).all()
        assert _seen(spoilt[[0, 2]]).all()


def test_static_cut_by_frame_reaches_the_border_away_from_the_object():
    boxes, contact = _scene()  # the object ends right of the static box's centre
    spoilt, _ = static_cut_by_frame(boxes, contact, np.random.default_rng(0), (H, W))
    assert (spoilt[2, :, 0] == 0).all() and (spoilt[2, :, 2] == boxes[2, :, 2]).all()
    mirrored = boxes.copy()
    mirrored[1, :, [0, 2]] = W - boxes[1, :, [2, 0]]
    spoilt, _ = static_cut_by_frame(mirrored, contact, np.random.default_rng(0), (H, W))
    assert (spoilt[2, :, 2] == W).all() and (spoilt[2, :, 0] == boxes[2, :, 0]).all()
    bottoms = [static_cut_by_frame(boxes, contact, np.random.default_rng(s), (H, W))[0][2, 0, 3] == H
               for s in range(20)]
    assert 0 < sum(bottoms) < 20
    in_front = boxes.copy()
    in_front[1, :, [1, 3]] = boxes[1, :, [1, 3]] + 10  # the object's bottom below the static's: in front of it
    assert not any(static_cut_by_frame(in_front, contact, np.random.default_rng(s), (H, W))[0][2, 0, 3] == H
                   for s in range(20))


def test_hand_partly_seen_keeps_a_window_of_half_to_two_thirds_of_the_frames_around_the_action_phase():
    boxes, contact = _scene()
    for seed in range(10):
        spoilt, _ = hand_partly_seen(boxes, contact, np.random.default_rng(seed), (H, W))
        seen = np.flatnonzero(_seen(spoilt[0]))
        assert 0.5 * N - 1 <= len(seen) <= 0.7 * N + 1
        assert np.all(np.diff(seen) == 1) and seen[0] <= 16 and seen[-1] >= 29
        assert _seen(spoilt[1:]).all()


def test_annotations_reach_the_demonstration_as_the_reader_delivers_them():
    boxes, contact = _scene()
    spoilt, phase = stops_early(boxes, contact, np.random.default_rng(1), (H, W))
    spoilt[1, 5:7] = np.nan  # a short gap: the reader interpolates it
    spoilt[0, 3:10] = np.nan  # a long one: not visible there
    video = as_annotations(spoilt, phase, video_id="7", action="pick_up")
    last = np.flatnonzero(_seen(spoilt).any(0))[-1]
    assert len(video.frames) == last + 1  # frames without any box are absent from the file
    assert video.phases["leave"] == (last + 2, N)
    demo, notes = something_else_demonstration(video, image_size=(H, W))
    # the demonstration ends with the annotations: the frames after them carry no evidence
    assert demo.num_frames == last + 1 and (demo.contact == phase[: last + 1]).all() and demo.contact[-1]
    assert demo.object_mask[-1].any() and demo.object_mask[5:7].any(axis=(1, 2)).all()
    assert not demo.hand_mask[3:10].any()
    assert any("the demonstration ends there" in note for note in notes)
    assert demo.object_noun is None  # a synthetic cuboid is not named: no noun to compare sizes with


def test_the_mix_is_deterministic_per_seed_and_covers_every_situation():
    assert all(real_scenarios(action, seed) == real_scenarios(action, seed) for action in ACTIONS for seed in range(20))
    assert all(real_scenarios(action, seed) for action in ACTIONS for seed in range(20))
    chosen = {name for action in ACTIONS for seed in range(20) for name in real_scenarios(action, seed)}
    assert chosen == {"stops_early", "enters_view", "static_cut_by_frame", "hand_partly_seen", "tall_thin"}
    assert "stops_early" not in real_scenarios("put_onto", 0)


@pytest.mark.slow
def test_a_real_scenario_demonstration_keeps_its_truth_and_its_situations():
    seed = next(s for s in range(20) if set(real_scenarios("pick_up", s)) == {"stops_early", "hand_partly_seen"})
    demo = make_demonstration("pick_up", seed=seed, image_size=(H, W), duration=4.0, input="boxes",
                              scenarios="real")
    whole = make_demonstration("pick_up", seed=seed, image_size=(H, W), duration=4.0, input="boxes")
    # The annotations stop 9-21 frames early: the demonstration ends with them, the object held.
    assert 9 <= whole.num_frames - demo.num_frames <= 21 and demo.contact[-1]
    seen = demo.object_mask.any(axis=(1, 2)) | demo.hand_mask.any(axis=(1, 2))
    assert seen[-1] and len(demo.truth["object_pos"]) == demo.num_frames
    thin = next(s for s in range(20) if "tall_thin" in real_scenarios("pick_up", s))
    thin_demo = make_demonstration("pick_up", seed=thin, image_size=(H, W), input="boxes", scenarios="real")
    size = thin_demo.truth["object_size"]
    assert all(lo <= edge <= hi for edge, (lo, hi) in zip(size, TALL_THIN))


def test_real_scenarios_need_box_input():
    with pytest.raises(ValueError, match="scenarios"):
        make_demonstration("pick_up", input="masks", scenarios="real")


@pytest.mark.parametrize("scenarios", ["narrow", "turned"])
def test_static_box_scenarios_need_a_put_action(scenarios):
    with pytest.raises(ValueError, match="without one: pick_up"):
        make_demonstration("pick_up", input="boxes", scenarios=scenarios)


def static_yaw(truth: dict) -> float:
    """The first static box's yaw [rad] from its ground-truth rotation."""
    rotation = truth["static_rot"][0]
    return float(np.arctan2(rotation[1, 0], rotation[0, 0]))


def object_yaw(truth: dict) -> float:
    """The object's first yaw [rad] from its ground-truth rotation."""
    rotation = truth["object_rot"][0]
    return float(np.arctan2(rotation[1, 0], rotation[0, 0]))


def test_turned_static_boxes_turn_the_same_scene_farther():
    yaws = []
    for seed in range(4):
        kwargs = dict(seed=seed, image_size=(H, W), duration=2.0, input="boxes")
        plain = make_demonstration("put_behind", **kwargs).truth
        turned = make_demonstration("put_behind", scenarios="turned", **kwargs).truth
        assert np.allclose(turned["static_size"], plain["static_size"])  # the same scene, only turned
        assert abs(static_yaw(turned)) <= TURNED_STATIC_YAW
        assert static_yaw(turned) == pytest.approx(static_yaw(plain) * TURNED_STATIC_YAW / Variant.static_yaw)
        yaws.append(abs(static_yaw(turned)))
    assert max(yaws) > Variant.static_yaw  # beyond what the plain scenes ever draw


@pytest.mark.parametrize("action", ["put_onto", "put_behind"])
def test_narrow_static_boxes_are_narrower_than_the_object_and_deep(action):
    for seed in range(2):
        truth = make_demonstration(action, seed=seed, image_size=(H, W), duration=2.0, input="boxes",
                                   scenarios="narrow").truth
        (low, high), (shallow, deep) = NARROW_STATIC
        width, depth = truth["static_size"][0, :2]
        assert low * truth["object_size"][0] <= width <= high * truth["object_size"][0]
        assert shallow <= depth <= deep
    plain = make_demonstration(action, seed=0, image_size=(H, W), duration=2.0, input="boxes").truth
    assert plain["static_size"][0, 0] > plain["object_size"][0]


def test_askew_objects_are_flat_scenes_turned_farther_but_pushed_ones_stay_square_on():
    yaws = []
    for seed in range(4):
        kwargs = dict(seed=seed, image_size=(H, W), duration=2.0, input="boxes")
        flat = make_demonstration("put_next_to", scenarios="flat", **kwargs).truth
        askew = make_demonstration("put_next_to", scenarios="askew", **kwargs).truth
        assert np.allclose(askew["object_size"], flat["object_size"])  # the same long thin object
        assert abs(object_yaw(askew)) <= ASKEW_OBJECT_YAW
        yaws.append(abs(object_yaw(askew)))
        assert object_yaw(make_demonstration("push_left_to_right", scenarios="askew", **kwargs).truth) == 0.0
    assert max(yaws) > Variant.object_yaw  # beyond what the plain scenes ever draw
