"""Synthetic demonstrations: valid files, physically consistent truth that meets the metric, real noise."""

from dataclasses import replace

import cv2
import numpy as np
import pytest

from warpskill.contract.actions import ACTIONS
from warpskill.contract.demonstration import Demonstration
from warpskill.contract.evaluation import evaluate
from warpskill.contract.reconstruction import Reconstruction
from warpskill.synthetic import NOISE_LEVELS, make_demonstration


@pytest.mark.parametrize("action", ACTIONS)
def test_truth_of_every_action_meets_the_success_criteria(action):
    demo = make_demonstration(action, seed=1, noise="none", image_size=(120, 214))
    truth = Reconstruction(**demo.truth)
    result = evaluate(truth, action)
    assert result.success, result.checks
    assert demo.num_static == (1 if action.startswith("put_") else 0)
    # Without noise the contact signal is the engine's own grasp state.
    np.testing.assert_array_equal(demo.contact, truth.grasped > 0.5)


def test_noise_spoils_masks_and_contact_but_keeps_them_valid():
    clean = make_demonstration("put_behind", seed=0, noise="none", image_size=(120, 214))
    noisy = make_demonstration("put_behind", seed=0, noise="high", image_size=(120, 214))
    np.testing.assert_allclose(clean.truth["object_pos"], noisy.truth["object_pos"])
    changed = (clean.object_mask != noisy.object_mask).mean()
    assert 0.001 < changed < 0.2
    assert noisy.hand_mask.any() and noisy.object_mask.any() and noisy.contact.any()
    assert set(NOISE_LEVELS) == {"none", "low", "moderate", "high"}


def test_spurious_blobs_are_cleaned_away_as_the_readers_clean_a_segmenters_masks():
    blobs = replace(NOISE_LEVELS["none"], blob_rate=1.0)  # a spurious blob in every frame
    demo = make_demonstration("put_behind", seed=0, noise=blobs)
    exact = make_demonstration("put_behind", seed=0, noise="none")
    for mask in (demo.hand_mask, demo.object_mask, *demo.static_mask):
        assert max(_blob_count(frame) for frame in mask) == 1
    # Where the object outsizes any blob (axes up to 7 px), what is kept is the object.
    shown = exact.object_mask.sum(axis=(1, 2)) > 400
    assert shown.sum() > 10
    assert not (demo.object_mask[shown] & ~exact.object_mask[shown]).any()


def _blob_count(frame: np.ndarray) -> int:
    return cv2.connectedComponents(frame.astype(np.uint8), connectivity=8)[0] - 1


def test_round_trip_through_the_file_format(tmp_path):
    demo = make_demonstration("pick_up", seed=0, image_size=(60, 107))
    demo.save(tmp_path / "demo.npz")
    loaded = Demonstration.load(tmp_path / "demo.npz")
    np.testing.assert_array_equal(loaded.object_mask, demo.object_mask)
    assert loaded.action == "pick_up"
    np.testing.assert_allclose(loaded.truth["hand_pos"], demo.truth["hand_pos"])


def test_same_seed_same_demonstration_and_unknown_action_rejected():
    a = make_demonstration("push_left_to_right", seed=3, image_size=(60, 107))
    b = make_demonstration("push_left_to_right", seed=3, image_size=(60, 107))
    np.testing.assert_array_equal(a.hand_mask, b.hand_mask)
    with pytest.raises(ValueError, match="pull_left_to_right"):
        make_demonstration("throw")


# --------------------------------------------------------------------------- box input


@pytest.mark.parametrize("action, seed", [("pick_up", 0), ("pick_up", 1), ("pick_up", 2), ("put_onto", 0),
                                          ("put_behind", 1), ("push_left_to_right", 0)])
def test_box_demonstrations_keep_a_truth_that_meets_the_criteria(action, seed):
    demo = make_demonstration(action, seed=seed, input="boxes", image_size=(120, 214))
    result = evaluate(Reconstruction(**demo.truth), action)
    assert result.success, result.checks
    # Every mask is the ellipse inscribed in a box: about pi/4 of its bounding box.
    for mask in (demo.hand_mask, demo.object_mask):
        k = int(np.argmax(mask.reshape(len(mask), -1).sum(1)))
        rows, cols = np.nonzero(mask[k])
        ratio = len(rows) / ((np.ptp(rows) + 1) * (np.ptp(cols) + 1))
        assert 0.65 < ratio < 0.9


def test_box_pick_ups_end_their_action_phase_while_the_hand_still_holds_the_object():
    from warpskill.synthetic import PICK_UP_ENDINGS

    assert PICK_UP_ENDINGS == ("held", "towards camera", "out of view")
    for seed in range(3):
        demo = make_demonstration("pick_up", seed=seed, input="boxes", image_size=(120, 214))
        grasped = demo.truth["grasped"] > 0.5
        assert grasped[-1]  # held to the end ...
        assert np.flatnonzero(demo.contact)[-1] < len(grasped) - 5  # ... but the phase ended before
    gone = make_demonstration("pick_up", seed=2, input="boxes", image_size=(120, 214))
    assert not gone.object_mask[-1].any()  # lifted out of the view


def test_box_input_is_checked_and_the_mask_input_unchanged():
    with pytest.raises(ValueError, match="input"):
        make_demonstration("pick_up", input="points")
    a = make_demonstration("put_onto", seed=0, image_size=(60, 107))
    b = make_demonstration("put_onto", seed=0, image_size=(60, 107), input="masks")
    np.testing.assert_array_equal(a.object_mask, b.object_mask)


def test_the_benchmark_measures_errors_and_scale_against_the_truth():
    from warpskill.bench.synthetic import camera_frame_errors, error_table

    demo = make_demonstration("put_onto", seed=0, noise="none", image_size=(60, 107))
    truth = Reconstruction(**demo.truth)
    exact = camera_frame_errors(truth, demo.truth)
    assert exact["scale"] == pytest.approx(1.0) and max(v for k, v in exact.items() if k != "scale") < 1e-9
    # The same scene scaled about the camera: every camera-frame distance scales.
    fields = dict(demo.truth)
    for key in ("hand_pos", "object_pos", "object_size", "static_pos", "static_size", "camera_height"):
        fields[key] = 0.8 * np.asarray(demo.truth[key])
    shrunk = camera_frame_errors(Reconstruction(**fields), demo.truth)
    assert shrunk["scale"] == pytest.approx(0.8)
    assert shrunk["static_size"] == pytest.approx(0.2 * np.abs(demo.truth["static_size"][0]).mean())
    # Put onto: the object is let go on the static's top, 0.8 times as high in the scaled scene.
    assert shrunk["release_height"] == pytest.approx(0.2 * demo.truth["static_size"][0, 2], rel=0.05)
    table = error_table({"full method": [exact, shrunk]})
    assert "scale" in table and "0.90" in table


def test_the_action_table_reports_success_and_errors_per_action():
    from warpskill.bench.outcomes import CaseOutcome, action_error_table

    cases = [CaseOutcome("put_onto_0", "put_onto", True, [], {"centre": 0.02, "static_size": 0.01, "release_height": 0.0}),
             CaseOutcome("put_onto_1", "put_onto", False, ["on_static_top"], {"centre": 0.04, "release_height": 0.1}),
             CaseOutcome("pick_up_0", "pick_up", True, [], {"centre": 0.05})]
    lines = action_error_table(cases).splitlines()
    assert lines[2] == "| put_onto | 1/2 | 3.0 | 1.0 | 5.0 |"
    assert lines[3] == "| pick_up | 1/1 | 5.0 | - | - |"
