"""Tests for warpskill.contract.demonstration: the demonstration file of docs/formats.md."""

from __future__ import annotations

import gc
import warnings

import numpy as np
import pytest
from record_support import assert_save_is_atomic

from warpskill.contract.camera import Intrinsics
from warpskill.contract.demonstration import Demonstration, DemonstrationError

N, H, W = 4, 6, 8


def valid_arrays() -> dict[str, np.ndarray]:
    """A small valid demonstration as the arrays of its file (every optional key present)."""
    hand = np.zeros((N, H, W), np.uint8)
    hand[:, 0:2, 0:3] = 1
    obj = np.zeros((N, H, W), np.uint8)
    obj[:, 3:5, 4:7] = 1
    obj[2] = 0  # not visible in one frame: allowed
    static = np.zeros((2, N, H, W), np.uint8)
    static[0, :, 4:6, 0:2] = 1
    static[1, :, 5:6, 6:8] = 1
    return {
        "hand_mask": hand,
        "object_mask": obj,
        "static_mask": static,
        "contact": np.array([0, 1, 1, 0], np.uint8),
        "fps": np.array(12.0),
        "camera_K": np.array([[7.0, 0.0, 4.0], [0.0, 6.0, 3.0], [0.0, 0.0, 1.0]]),
        "action": np.array("put_onto"),
        "truth_object_pos": np.arange(N * 3, dtype=float).reshape(N, 3),
        "truth_static_size": np.full((2, 3), 0.1),
        "truth_action": np.array("put_onto"),
    }


def load_from_arrays(arrays: dict[str, np.ndarray], tmp_path) -> Demonstration:
    """Write the arrays as a file with plain numpy and load it."""
    path = tmp_path / "demo.npz"
    np.savez_compressed(path, **arrays)
    return Demonstration.load(path)


def assert_same(a: Demonstration, b: Demonstration) -> None:
    for name in ("hand_mask", "object_mask", "static_mask", "contact"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert getattr(b, name).dtype == bool
    assert a.fps == b.fps
    np.testing.assert_array_equal(a.intrinsics.K, b.intrinsics.K)
    assert a.intrinsics.image_size == b.intrinsics.image_size
    assert a.action == b.action
    assert a.truth.keys() == b.truth.keys()
    for name in a.truth:
        np.testing.assert_array_equal(a.truth[name], b.truth[name])


def test_round_trip(tmp_path):
    demo = load_from_arrays(valid_arrays(), tmp_path)
    assert (demo.num_frames, demo.image_size, demo.num_static) == (N, (H, W), 2)
    assert demo.duration == pytest.approx((N - 1) / 12.0)
    assert demo.action == "put_onto"
    assert sorted(demo.truth) == ["action", "object_pos", "static_size"]
    path = tmp_path / "again.npz"
    demo.save(path)
    assert_same(demo, Demonstration.load(path))
    with np.load(path) as saved:
        assert saved["hand_mask"].dtype == np.uint8
        assert saved["static_mask"].shape == (2, N, H, W)
        assert "truth_object_pos" in saved.files


def test_minimal_file_defaults_and_round_trip(tmp_path):
    arrays = {k: valid_arrays()[k] for k in ("hand_mask", "object_mask", "contact", "fps")}
    demo = load_from_arrays(arrays, tmp_path)
    assert demo.num_static == 0 and demo.static_mask.shape == (0, N, H, W)
    assert demo.action is None and demo.truth == {}
    expected = Intrinsics.default(H, W)
    np.testing.assert_allclose(demo.intrinsics.K, expected.K)
    assert demo.intrinsics.image_size == (H, W)
    path = tmp_path / "again.npz"
    demo.save(path)
    with np.load(path) as saved:
        assert "static_mask" not in saved.files and "action" not in saved.files
    assert_same(demo, Demonstration.load(path))


def test_single_static_mask_without_k_axis(tmp_path):
    arrays = valid_arrays()
    arrays["static_mask"] = arrays["static_mask"][0]
    arrays["truth_static_size"] = arrays["truth_static_size"][:1]
    assert load_from_arrays(arrays, tmp_path).static_mask.shape == (1, N, H, W)
    assert Demonstration.from_file_arrays(arrays).num_static == 1


@pytest.mark.parametrize(
    "encode",
    [
        lambda m: m.astype(bool),
        lambda m: m.astype(np.uint8),
        lambda m: m.astype(np.uint8) * 255,
        lambda m: m.astype(np.int64),
        lambda m: m.astype(np.float32),
        lambda m: m.astype(np.float64) * 255,
    ],
    ids=["bool", "0/1 uint8", "0/255 uint8", "0/1 int64", "0/1 float32", "0/255 float64"],
)
def test_mask_encodings_accepted(encode, tmp_path):
    arrays = valid_arrays()
    reference = Demonstration.from_file_arrays(arrays)
    for key in ("hand_mask", "object_mask", "static_mask", "contact"):
        arrays[key] = encode(arrays[key].astype(bool))
    assert_same(reference, Demonstration.from_file_arrays(arrays))
    assert_same(reference, load_from_arrays(arrays, tmp_path))


def _set(key, value):
    return lambda arrays: arrays.__setitem__(key, value)


def _edit(key, edit):
    return lambda arrays: arrays.__setitem__(key, edit(arrays[key].copy()))


def _nan_in(array):
    array = array.astype(float)
    array.flat[0] = np.nan
    return array


def _bad_value(value, index=0):
    def edit(array):
        array.flat[index] = value
        return array

    return edit


BAD_INPUTS = {
    # key, mutation of valid_arrays(), text the message must contain
    "hand_mask 2-D": ("hand_mask", _edit("hand_mask", lambda m: m[0]), "dimensions"),
    "object_mask other H": ("object_mask", _edit("object_mask", lambda m: m[:, :-1]), "shape"),
    "object_mask other N": ("object_mask", _edit("object_mask", lambda m: m[:-1]), "shape"),
    "static_mask other W": ("static_mask", _edit("static_mask", lambda m: m[..., :-1]), "shape"),
    "static_mask 5-D": ("static_mask", _edit("static_mask", lambda m: m[None]), "dimensions"),
    "contact other N": ("contact", _set("contact", np.array([0, 1, 1], np.uint8)), "shape"),
    "contact 2-D": ("contact", _set("contact", np.ones((N, 1), np.uint8)), "dimensions"),
    "hand_mask value 2": ("hand_mask", _edit("hand_mask", _bad_value(2)), "value 2"),
    "object_mask 1 and 255": ("object_mask", _edit("object_mask", lambda m: m * 255 + (m == 0)), "1 and 255"),
    "object_mask NaN": ("object_mask", _edit("object_mask", _nan_in), "NaN"),
    "hand_mask strings": ("hand_mask", _edit("hand_mask", lambda m: m.astype(str)), "dtype"),
    "contact value 3": ("contact", _edit("contact", _bad_value(3)), "value 3"),
    "fps zero": ("fps", _set("fps", np.array(0.0)), "> 0"),
    "fps negative": ("fps", _set("fps", np.array(-12.0)), "> 0"),
    "fps NaN": ("fps", _set("fps", np.array(np.nan)), "NaN"),
    "fps inf": ("fps", _set("fps", np.array(np.inf)), "NaN or inf"),
    "fps vector": ("fps", _set("fps", np.array([12.0])), "scalar"),
    "hand never visible": ("hand_mask", _edit("hand_mask", np.zeros_like), "empty in every frame"),
    "object never visible": ("object_mask", _edit("object_mask", np.zeros_like), "empty in every frame"),
    "contact never on": ("contact", _edit("contact", np.zeros_like), "never on"),
    "unknown action": ("action", _set("action", np.array("throw")), "pull_left_to_right"),
    "camera_K shape": ("camera_K", _edit("camera_K", lambda k: k[:2]), "shape"),
    "camera_K NaN": ("camera_K", _edit("camera_K", _nan_in), "NaN"),
    "camera_K skew": ("camera_K", _edit("camera_K", _bad_value(0.5, index=1)), "[0, 0, 1]"),
    "camera_K last row": ("camera_K", _edit("camera_K", lambda k: k * 2), "[0, 0, 1]"),
    "camera_K fx <= 0": ("camera_K", _edit("camera_K", lambda k: k * np.array([[-1], [1], [1]])), "focal"),
    "truth unknown key": ("truth_speed", _set("truth_speed", np.zeros(N)), "not a reconstruction key"),
    "truth other N": ("truth_object_pos", _edit("truth_object_pos", lambda a: a[:-1]), "N = 4"),
    "truth other K": ("truth_static_size", _edit("truth_static_size", lambda a: a[:1]), "K = 2"),
    "truth NaN": ("truth_object_pos", _edit("truth_object_pos", _nan_in), "NaN"),
    "truth bad action": ("truth_action", _set("truth_action", np.array("throw")), "unknown action"),
}


@pytest.mark.parametrize("case", BAD_INPUTS.values(), ids=BAD_INPUTS.keys())
@pytest.mark.parametrize("source", ["from_arrays", "load"])
def test_bad_input_names_key(case, source, tmp_path):
    key, mutate, problem = case
    arrays = valid_arrays()
    mutate(arrays)
    with pytest.raises(DemonstrationError) as error:
        if source == "load":
            load_from_arrays(arrays, tmp_path)
        else:
            Demonstration.from_file_arrays(arrays)
    message = str(error.value)
    assert f"{key}:" in message and problem in message
    if source == "load":
        assert str(tmp_path / "demo.npz") in message


@pytest.mark.parametrize("key", ["hand_mask", "object_mask", "contact", "fps"])
def test_missing_required_key(key, tmp_path):
    arrays = valid_arrays()
    del arrays[key]
    with pytest.raises(DemonstrationError, match=f"missing required key.*{key}"):
        load_from_arrays(arrays, tmp_path)


def test_unknown_key_rejected(tmp_path):
    arrays = valid_arrays()
    arrays["camera_k"] = arrays.pop("camera_K")  # a typo must not silently drop the intrinsics
    with pytest.raises(DemonstrationError, match="unknown key.*camera_k"):
        load_from_arrays(arrays, tmp_path)


def test_action_must_be_string_in_file(tmp_path):
    arrays = valid_arrays()
    arrays["action"] = np.array(3)
    with pytest.raises(DemonstrationError, match="action: expected a string"):
        load_from_arrays(arrays, tmp_path)


def test_not_an_npz(tmp_path):
    text = tmp_path / "notes.npz"
    text.write_text("not a zip archive")
    with pytest.raises(DemonstrationError, match="not a readable .npz"):
        Demonstration.load(text)
    single = tmp_path / "single.npy"
    np.save(single, valid_arrays()["hand_mask"])
    with pytest.raises(DemonstrationError, match="not an .npz archive"):
        Demonstration.load(single)
    with pytest.raises(FileNotFoundError):
        Demonstration.load(tmp_path / "absent.npz")
    with pytest.raises(DemonstrationError, match="not a readable .npz"):
        Demonstration.load(tmp_path)  # a folder


def test_a_corrupt_archive_leaves_no_file_open(tmp_path):
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"PK\x03\x04" + b"garbage" * 20)  # a zip's magic, then nothing readable
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(DemonstrationError, match="not a readable .npz"):
            Demonstration.load(broken)
        gc.collect()
    assert not [w for w in caught if issubclass(w.category, ResourceWarning)]


def test_corrupt_zip(tmp_path):
    path = tmp_path / "demo.npz"
    np.savez_compressed(path, **valid_arrays())
    data = bytearray(path.read_bytes())
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(bytes(data[: len(data) // 2]))
    with pytest.raises(DemonstrationError, match="truncated.npz"):
        Demonstration.load(truncated)
    data[60:90] = bytes(30)  # inside the first member's compressed data
    path.write_bytes(bytes(data))
    with pytest.raises(DemonstrationError, match="hand_mask: unreadable"):
        Demonstration.load(path)


def test_atomic_save_keeps_existing_file(tmp_path):
    demo = Demonstration.from_file_arrays(valid_arrays())
    assert_save_is_atomic(demo, tmp_path / "demo.npz",
                          lambda: demo.truth.update(grasp=np.array([lambda: None], dtype=object)))


def test_empty_frame_is_not_an_error():
    arrays = valid_arrays()
    arrays["hand_mask"][1:] = 0
    assert not Demonstration.from_file_arrays(arrays).hand_mask[1:].any()


def test_mask_stack_area_averages():
    demo = Demonstration.from_file_arrays(valid_arrays())
    stack = demo.mask_stack(3, 4)
    assert stack.shape == (N, 2 + 2, 3, 4) and stack.dtype == np.float32
    # Object pixels rows 3:5, columns 4:7 -> output rows 1:3 (half each), columns 2:4.
    expected = np.zeros((3, 4), np.float32)
    expected[1:3, 2] = 0.5
    expected[1:3, 3] = 0.25
    np.testing.assert_allclose(stack[0, 1], expected)
    np.testing.assert_array_equal(stack[2, 1], 0.0)  # invisible frame
    np.testing.assert_allclose(stack[:, 0].sum(axis=(1, 2)), demo.hand_mask.sum(axis=(1, 2)) / 4)
    full = demo.mask_stack(H, W)  # at the masks' own size: the masks themselves, as float32
    assert full.dtype == np.float32
    np.testing.assert_array_equal(full, np.stack([demo.hand_mask, demo.object_mask, *demo.static_mask], axis=1))


def test_resized_keeps_bool_masks_and_rescales_intrinsics():
    demo = Demonstration.from_file_arrays(valid_arrays())
    small = demo.resized(3, 4)
    assert small.image_size == (3, 4) and small.hand_mask.dtype == bool
    np.testing.assert_array_equal(small.object_mask[0], demo.mask_stack(3, 4)[0, 1] >= 0.5)
    np.testing.assert_allclose(small.intrinsics.K, demo.intrinsics.resized(3, 4).K)
    assert small.fps == demo.fps and small.action == demo.action
    np.testing.assert_array_equal(small.contact, demo.contact)


def test_mask_channels_are_mask_stacks_channels_at_full_size_as_bools():
    demo = Demonstration.from_file_arrays(valid_arrays())
    channels = demo.mask_channels()
    assert channels.dtype == bool and channels.shape == (N, 2 + 2, H, W)
    np.testing.assert_array_equal(channels, demo.mask_stack(H, W) > 0.5)
