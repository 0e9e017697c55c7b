"""A fast video thinned to the optimiser's rate: the frames kept, the contact's runs, the truth, the verdict."""

import numpy as np
import pytest

from warpskill.contract import Reconstruction, evaluate
from warpskill.contract.frame_rate import at_optimiser_rate, every_nth, frame_stride, kept_frames, thinned_contact
from warpskill.contract.reconstruction import FIELD_SHAPES
from warpskill.synthetic import make_demonstration


@pytest.fixture(scope="module")
def phone_clip():
    """A put_onto at a phone's 30 fps, small masks, with its ground truth."""
    return make_demonstration("put_onto", seed=0, noise="none", image_size=(60, 80), fps=30.0, duration=3.4)


def test_the_stride_brings_the_rate_nearest_12_fps_and_leaves_slow_videos_alone():
    strides = {fps: frame_stride(fps) for fps in (6, 12, 15, 18, 20, 24, 25, 29.97, 30, 50, 60, 120)}
    assert strides == {6: 1, 12: 1, 15: 1, 18: 1, 20: 2, 24: 2, 25: 2, 29.97: 3, 30: 3, 50: 4, 60: 5, 120: 10}
    assert all(frame_stride(fps / stride) == 1 for fps, stride in strides.items())  # thinning twice: nothing more
    assert list(kept_frames(10, 3)) == [0, 3, 6, 9]
    with pytest.raises(ValueError, match="fps must be positive"):
        frame_stride(0.0)


@pytest.mark.parametrize("stride", [2, 3, 5])
def test_each_contact_run_keeps_its_onset_and_release_within_half_a_stride(stride):
    rng = np.random.default_rng(stride)
    for _ in range(50):
        contact = np.zeros(rng.integers(20, 120), dtype=bool)
        onset = rng.integers(0, len(contact) - 1)
        release = rng.integers(onset, min(onset + 3 * stride, len(contact)))
        contact[onset : release + 1] = True
        thinned = thinned_contact(contact, stride)
        on = np.flatnonzero(thinned)
        assert len(thinned) == len(kept_frames(len(contact), stride))
        assert np.all(np.diff(on) == 1)  # one run stays one run, however short
        assert abs(on[0] * stride - onset) <= stride / 2
        last_kept = on[-1] == len(thinned) - 1 and release > on[-1] * stride  # the video's tail after it is not kept
        assert abs(on[-1] * stride - release) <= stride / 2 or last_kept


def test_a_30_fps_demonstration_is_its_every_third_frame_at_10_fps(phone_clip):
    demo = phone_clip
    thinned = at_optimiser_rate(demo)
    keep = np.arange(0, demo.num_frames, 3)
    assert thinned.fps == demo.fps / 3 == 10.0 and thinned.num_frames == len(keep) == 35
    assert thinned.duration == pytest.approx(demo.duration - (demo.num_frames - 1 - keep[-1]) / demo.fps)
    for name in ("hand_mask", "object_mask"):
        assert np.array_equal(getattr(thinned, name), getattr(demo, name)[keep])
    assert np.array_equal(thinned.static_mask, demo.static_mask[:, keep])
    assert thinned.intrinsics == demo.intrinsics and thinned.action == demo.action
    on, thin_on = np.flatnonzero(demo.contact), np.flatnonzero(thinned.contact)
    assert abs(keep[thin_on[0]] - on[0]) <= 1 and abs(keep[thin_on[-1]] - on[-1]) <= 1  # the grasp and the release
    assert thinned.truth["fps"] == 10.0
    assert np.allclose(thinned.truth["t"], keep / demo.fps)  # the video's clock
    for name, value in demo.truth.items():
        if FIELD_SHAPES[name][:1] == ("N",):
            assert np.array_equal(thinned.truth[name], value[keep]), name
        elif name != "fps":
            assert np.array_equal(thinned.truth[name], value), name
    assert at_optimiser_rate(thinned) is thinned


def test_the_true_motion_judged_at_10_fps_gets_the_full_rate_verdict(phone_clip):
    full, thinned = (Reconstruction(**demo.truth) for demo in (phone_clip, at_optimiser_rate(phone_clip)))
    judged = [evaluate(recon, "put_onto") for recon in (full, thinned)]
    assert judged[0].success and judged[1].checks == judged[0].checks


def test_a_12_fps_demonstration_is_left_as_it_is():
    demo = make_demonstration("pick_up", seed=0, noise="none", image_size=(60, 80), duration=2.0)
    assert at_optimiser_rate(demo) is demo and every_nth(demo, 1) is demo


def test_optimize_with_workers_hands_its_tasks_the_same_frames(phone_clip, tmp_path):
    from warpskill.cli.pipeline import _fitted

    slow, fast, corrupt = tmp_path / "slow.npz", tmp_path / "fast.npz", tmp_path / "corrupt.npz"
    make_demonstration("pick_up", seed=0, noise="none", image_size=(60, 80), duration=2.0).save(slow)
    phone_clip.save(fast)
    corrupt.write_bytes(b"not a zip")
    assert _fitted(slow) == slow and _fitted(corrupt) == corrupt  # read in the task, as before
    thinned = _fitted(fast)
    assert thinned.fps == 10.0 and np.array_equal(thinned.object_mask, at_optimiser_rate(phone_clip).object_mask)
