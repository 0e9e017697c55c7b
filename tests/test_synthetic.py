"""Synthetic demonstrations: valid files, physically consistent truth that meets the metric, real noise."""

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
