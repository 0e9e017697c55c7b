"""Fuzzing the contract's loaders and the data readers with generated malformed inputs (hypothesis).

Every generated case (demonstration / reconstruction / replay ``.npz`` arrays and bytes, mask
folders, label images, Something-Else JSON and CSVs, detections CSVs) must end in one of two
ways: a valid object (checked: finite, right shapes, binary masks), or the project's own error
(``DemonstrationError``, ``ReconstructionError``, or ``FileNotFoundError`` where a reader
documents it) whose message names the offending key, file or field. Any other exception
(``TypeError``, ``KeyError``, ``IndexError``, numpy's ``ValueError``, ``cv2.error``,
``zipfile.BadZipFile``, ...) fails the test, and so does a NaN in a loaded result.

The runs are derandomized (reproducible in CI) and small (arrays of a few pixels), so the
whole module runs its :data:`MIN_CASES` or more cases in well under a minute;
:func:`test_zz_enough_cases_were_generated` counts them. The plain tests after each
property are regressions for the bugs the fuzzer found.
"""

from __future__ import annotations

import collections
import csv
import io
import json
import math
import tempfile
import zipfile
from pathlib import Path

import cv2
import numpy as np
import pytest

pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from warpskill.contract.actions import ACTIONS
from warpskill.contract.demonstration import Demonstration, DemonstrationError
from warpskill.contract.reconstruction import (
    FIELD_SHAPES,
    Reconstruction,
    ReconstructionError,
)
from warpskill.contract.replay import Replay
from warpskill.data.boxes.something_else import (
    read_something_else,
    something_else_demonstration,
)
from warpskill.data.contact import IN_CONTACT, NO_CONTACT, UNKNOWN
from warpskill.data.readers.contact_files import read_detections
from warpskill.data.readers.mask_files import davis_palette, read_label_images, read_mask_folders

MIN_CASES = 1000
"""Generated cases the module must run in total (the issue's acceptance: >= 1000 in < 60 s)."""

CASES: collections.Counter[str] = collections.Counter()
"""Property test name -> cases it ran in this session."""


def fuzz(max_examples: int) -> settings:
    """Settings of every property here: reproducible (derandomized), no deadline, no database."""
    return settings(
        max_examples=max_examples,
        deadline=None,
        derandomize=True,
        database=None,
        print_blob=False,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
    )


DEMO_KEYS = ("hand_mask", "object_mask", "static_mask", "contact", "fps", "camera_K", "action")


def outcome(call, errors, names):
    """``(result, None)`` or ``(None, error)`` for one of ``errors`` whose message names one of ``names``.

    Any other exception propagates and fails the test (hypothesis then shrinks the case).
    """
    try:
        result = call()
    except errors as exc:
        message = str(exc)
        event(f"{type(exc).__name__}")  # --hypothesis-show-statistics: how the cases ended
        assert any(name in message for name in names), f"{type(exc).__name__}: {message!r} names none of {sorted(names)}"
        return None, exc
    event("loaded")
    return result, None


def check_demonstration(demo: Demonstration) -> None:
    """Invariants of a loaded demonstration: binary masks of one (N, H, W), contact on somewhere, finite numbers."""
    assert isinstance(demo, Demonstration)
    n, h, w = demo.hand_mask.shape
    for mask in (demo.hand_mask, demo.object_mask, demo.static_mask, demo.contact):
        assert mask.dtype == bool
    assert demo.object_mask.shape == (n, h, w) and demo.static_mask.shape[1:] == (n, h, w)
    assert demo.static_mask.ndim == 4 and demo.contact.shape == (n,)
    assert demo.hand_mask.any() and demo.object_mask.any() and demo.contact.any()
    assert isinstance(demo.fps, float) and math.isfinite(demo.fps) and demo.fps > 0
    K = demo.intrinsics.K
    assert K.shape == (3, 3) and np.isfinite(K).all() and K[0, 0] > 0 and K[1, 1] > 0
    assert tuple(demo.intrinsics.image_size) == (h, w)
    assert demo.action is None or demo.action in ACTIONS
    for name, value in demo.truth.items():
        assert name in FIELD_SHAPES
        if value.dtype.kind in "biuf":
            assert np.isfinite(value).all(), name


def check_reconstruction(recon: Reconstruction) -> None:
    """Invariants of a loaded reconstruction: every field's shape, finite floats, positive sizes."""
    assert isinstance(recon, Reconstruction)
    dims = {"N": recon.num_frames, "K": recon.num_static}
    assert recon.num_frames >= 1
    for name, template in FIELD_SHAPES.items():
        value = getattr(recon, name)
        assert isinstance(value, np.ndarray), name
        assert value.shape == tuple(dims.get(size, size) for size in template), name
        if name == "action":
            assert value.dtype.kind == "U" and str(value) in ("", *ACTIONS)
        elif name in ("options", "object_noun", "hypotheses"):
            assert value.dtype.kind == "U"
        elif name == "image_size":
            assert value.dtype == np.int64 and (value > 0).all()
        else:
            assert value.dtype == np.float64 and np.isfinite(value).all(), name
    assert recon.fps > 0


# --------------------------------------------------------------------------- arrays


def rng_of(seed: int) -> np.random.Generator:
    return np.random.default_rng(seed)


def random_mask(rng: np.random.Generator, shape: tuple[int, ...], nonempty: bool = True) -> np.ndarray:
    mask = rng.random(shape) < 0.4
    if nonempty and mask.size:
        mask.flat[rng.integers(mask.size)] = True
    return mask


MASK_ENCODINGS = ("bool", "u8_01", "u8_0255", "i64_01", "i16_0255", "f32_01", "f64_0255", "f16_01")


def encode_mask(mask: np.ndarray, encoding: str) -> np.ndarray:
    """A bool mask in one of the encodings the contract accepts (bool, 0/1, 0/255)."""
    if encoding == "bool":
        return mask.copy()
    kind, values = encoding.split("_")
    dtype = {"u8": np.uint8, "i64": np.int64, "i16": np.int16, "f32": np.float32, "f64": np.float64, "f16": np.float16}[kind]
    return mask.astype(dtype) * (255 if values == "0255" else 1)


def pinhole(h: int, w: int, f: float = 50.0) -> np.ndarray:
    return np.array([[f, 0.0, w / 2], [0.0, f, h / 2], [0.0, 0.0, 1.0]])


def valid_reconstruction_arrays(rng: np.random.Generator, n: int, k: int, action: str = "") -> dict[str, np.ndarray]:
    """Reconstruction fields of N frames and K static objects (well-formed, random numbers)."""
    rot = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    return {
        "fps": np.array(float(rng.uniform(1, 60))),
        "t": np.arange(n) / 12.0,
        "hand_pos": rng.normal(size=(n, 3)),
        "hand_rot": rot,
        "grasp": rng.normal(size=n),
        "grasped": rng.random(n),
        "object_pos": rng.normal(size=(n, 3)) + [0, 0, 0.05],
        "object_rot": rot.copy(),
        "object_size": rng.uniform(0.01, 0.2, 3),
        "static_pos": rng.normal(size=(k, 3)),
        "static_rot": np.broadcast_to(np.eye(3), (k, 3, 3)).copy(),
        "static_size": rng.uniform(0.01, 0.3, (k, 3)),
        "camera_K": pinhole(24, 32),
        "camera_elevation": np.array(0.5),
        "camera_height": np.array(0.4),
        "image_size": np.array([24, 32]),
        "action": np.array(action),
        "loss": np.array(float(rng.random())),
    }


def bad_number_array(rng: np.random.Generator, shape: tuple[int, ...], how: str) -> np.ndarray:
    """An array of ``shape`` (or near it) that is wrong in the way ``how`` names."""
    size = int(np.prod(shape))
    if how == "nan" or how == "inf" or how == "-inf":
        array = rng.random(shape)
        if size:
            array.flat[rng.integers(size)] = float(how)
        return array
    if how == "str":
        return np.full(shape, "1")
    if how == "bytes":
        return np.full(shape, b"1")
    if how == "complex":
        return np.ones(shape, dtype=complex)
    if how == "bool":
        return np.ones(shape, dtype=bool)
    if how == "stray":
        array = np.zeros(shape, dtype=np.int16)
        if size:
            array.flat[rng.integers(size)] = rng.choice([2, -1, 7, 128, 256, 1000])
        return array
    if how == "half":
        return np.full(shape, 0.5)
    if how == "mixed_1_255":
        array = np.zeros(shape, dtype=np.uint8)
        if size >= 2:
            array.flat[0], array.flat[1] = 1, 255
        return array
    if how == "zeros":
        return np.zeros(shape, dtype=np.uint8)
    if how == "ndim":
        return np.ones(tuple(rng.integers(0, 4, size=int(rng.integers(0, 6)))), dtype=np.uint8)
    if how == "more":
        return np.ones((shape[0] + 1, *shape[1:]) if shape else (2,), dtype=np.uint8)
    if how == "less":
        return np.ones((max(shape[0] - 1, 0), *shape[1:]) if shape else (0,), dtype=np.uint8)
    if how == "wider":
        return np.ones((*shape[:-1], shape[-1] + 1) if shape else (1, 1), dtype=np.uint8)
    if how == "empty":
        return np.zeros((0,) * max(len(shape), 1), dtype=np.uint8)
    raise AssertionError(how)


BAD_HOWS = ("nan", "inf", "-inf", "str", "bytes", "complex", "bool", "stray", "half", "mixed_1_255", "zeros", "ndim",
            "more", "less", "wider", "empty")


def npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    return buffer.getvalue()


# --------------------------------------------------------------------------- demonstrations


@st.composite
def demonstration_arrays(draw, mutate: bool = True):
    """(arrays of a demonstration file, names an error may cite, the bool masks before encoding)."""
    rng = rng_of(draw(st.integers(0, 2**32 - 1)))
    n, h, w = draw(st.integers(1, 4)), draw(st.integers(1, 6)), draw(st.integers(1, 6))
    hand, obj = random_mask(rng, (n, h, w)), random_mask(rng, (n, h, w))
    contact = random_mask(rng, (n,))
    arrays = {
        "hand_mask": encode_mask(hand, draw(st.sampled_from(MASK_ENCODINGS))),
        "object_mask": encode_mask(obj, draw(st.sampled_from(MASK_ENCODINGS))),
        "contact": encode_mask(contact, draw(st.sampled_from(("bool", "u8_01", "i64_01", "f64_01", "u8_0255")))),
        "fps": np.array(draw(st.one_of(st.floats(0.1, 240.0), st.integers(1, 120)))),
    }
    static = draw(st.sampled_from(("none", "nhw", "knhw", "k0")))
    k = {"none": 0, "nhw": 1, "knhw": draw(st.integers(1, 3)), "k0": 0}[static]
    if static == "nhw":
        arrays["static_mask"] = encode_mask(random_mask(rng, (n, h, w), False), draw(st.sampled_from(MASK_ENCODINGS)))
    elif static in ("knhw", "k0"):
        arrays["static_mask"] = encode_mask(random_mask(rng, (k, n, h, w), False), draw(st.sampled_from(MASK_ENCODINGS)))
    if draw(st.booleans()):
        arrays["camera_K"] = pinhole(h, w, draw(st.floats(1.0, 1e4)))
    if draw(st.booleans()):
        arrays["action"] = np.array(draw(st.sampled_from(ACTIONS)))
    if draw(st.booleans()):
        truth = valid_reconstruction_arrays(rng, n, k, str(arrays.get("action", "")))
        for name in draw(st.lists(st.sampled_from(sorted(truth)), max_size=5, unique=True)):
            arrays["truth_" + name] = truth[name]
    names = set()
    if mutate:
        for _ in range(draw(st.integers(1, 3))):
            names |= draw(demonstration_mutation(arrays, rng, (n, h, w)))
        if "static_mask" in names:  # K is taken from it, and the truth_static_* keys are checked against K
            names.add("truth_")
    return arrays, names, (hand, obj, contact)


@st.composite
def demonstration_mutation(draw, arrays, rng, nhw):
    """Break ``arrays`` in one way; returns the keys an error may name."""
    n, h, w = nhw
    kind = draw(st.sampled_from(("drop", "extra", "replace", "replace", "replace", "special", "truth")))
    if kind == "drop":
        key = draw(st.sampled_from(sorted(arrays)))
        del arrays[key]
        return {key}
    if kind == "extra":
        key = draw(st.one_of(
            st.sampled_from(("hand", "masks", "Hand_mask", "contacts", "truth", "static_masks", "camera_k", "frame_rate")),
            st.text("abcdefghijklmnopqrstuvwxyz_0123456789", min_size=1, max_size=10),
        ))
        if key in DEMO_KEYS or key.startswith("truth_"):
            key = "x_" + key
        arrays[key] = np.zeros(int(rng.integers(0, 3)))
        return {key}
    if kind == "truth":
        name = draw(st.sampled_from(sorted(FIELD_SHAPES) + ["bogus", "hand_mask"]))
        dims = {"N": n, "K": len(arrays.get("static_mask", ())) if np.ndim(arrays.get("static_mask")) == 4 else 1}
        shape = tuple(dims.get(size, size) for size in FIELD_SHAPES.get(name, (2,)))
        how = draw(st.sampled_from(("nan", "inf", "str", "complex", "ndim", "more", "wider", "zeros")))
        arrays["truth_" + name] = bad_number_array(rng, shape, how) if how != "zeros" else np.zeros(shape)
        return {"truth_" + name, "static_mask", "truth_"}
    if kind == "special":
        key = draw(st.sampled_from(("fps", "camera_K", "action", "static_mask")))
        if key == "fps":
            arrays["fps"] = draw(st.sampled_from((
                np.array(np.nan), np.array(np.inf), np.array(-np.inf), np.array(-1.0), np.array(0.0), np.array(-0.0),
                np.array([30.0]), np.array(0), np.array(-5), np.array(True), np.array("30"), np.array(30 + 0j),
                np.array(np.float16(np.nan)), np.array(1e-300), np.array(1e308), np.array(np.uint8(12)),
            )))
        elif key == "camera_K":
            K = pinhole(h, w)
            variant = draw(st.sampled_from(("nan", "inf", "zeros", "neg_f", "skew", "k22", "shape", "str", "int",
                                            "other_size", "huge", "row_swap")))
            if variant == "nan":
                K[rng.integers(3), rng.integers(3)] = np.nan
            elif variant == "inf":
                K[0, 0] = np.inf
            elif variant == "zeros":
                K = np.zeros((3, 3))
            elif variant == "neg_f":
                K[1, 1] = -K[1, 1]
            elif variant == "skew":
                K[0, 1] = 0.5
            elif variant == "k22":
                K[2, 2] = 2.0
            elif variant == "shape":
                K = K[:2, :]
            elif variant == "str":
                K = K.astype(str)
            elif variant == "int":
                K = K.astype(np.int64)  # rounds cx, cy: still a valid pinhole
            elif variant == "other_size":
                K = pinhole(h + 1, w + 1)  # fine: K does not fix the image size
            elif variant == "huge":
                K[0, 0] = K[1, 1] = 1e300
            elif variant == "row_swap":
                K = K[::-1]
            arrays["camera_K"] = K
        elif key == "action":
            arrays["action"] = draw(st.one_of(
                st.text(max_size=20).map(np.array),
                st.sampled_from((np.array(b"pick_up"), np.array(3), np.array(["pick_up"]), np.array(""),
                                 np.array("Pick_Up"), np.array(" pick_up"), np.array(np.nan))),
            ))
        else:
            k = int(rng.integers(0, 3))
            shape = draw(st.sampled_from(((k, n + 1, h, w), (k, n, h, w + 1), (h, w), (1, k, n, h, w), (n + 1, h, w),
                                          (k, n, h, w))))
            arrays["static_mask"] = random_mask(rng, shape, False).astype(np.uint8)
        return {key}
    key = draw(st.sampled_from(("hand_mask", "object_mask", "contact", "fps", "static_mask", "camera_K", "action")))
    shape = {"hand_mask": (n, h, w), "object_mask": (n, h, w), "static_mask": (n, h, w), "contact": (n,), "fps": (),
             "camera_K": (3, 3), "action": ()}[key]
    arrays[key] = bad_number_array(rng, shape, draw(st.sampled_from(BAD_HOWS)))
    # A hand mask of another shape changes what every other key is checked against.
    return set(DEMO_KEYS) | {"truth_"} if key == "hand_mask" else {key}


@pytest.mark.slow
@fuzz(450)
@given(demonstration_arrays())
def test_malformed_demonstration_files_raise_demonstration_error(case):
    CASES["demonstration arrays"] += 1
    arrays, names, _ = case
    buffer = io.BytesIO(npz_bytes(arrays))
    demo, error = outcome(lambda: Demonstration.load(buffer), DemonstrationError, names)
    if error is None:
        check_demonstration(demo)
    else:
        assert str(buffer) in str(error)  # the file is named too


@fuzz(120)
@given(demonstration_arrays(mutate=False))
def test_valid_demonstrations_load_in_every_mask_encoding(case):
    """bool, 0/1 and 0/255 masks of any dtype, (N, H, W) or (K, N, H, W) static masks: all accepted."""
    CASES["valid demonstrations"] += 1
    arrays, _, (hand, obj, contact) = case
    demo = Demonstration.load(io.BytesIO(npz_bytes(arrays)))
    check_demonstration(demo)
    np.testing.assert_array_equal(demo.hand_mask, hand)
    np.testing.assert_array_equal(demo.object_mask, obj)
    np.testing.assert_array_equal(demo.contact, contact)
    if "static_mask" in arrays:
        expected = arrays["static_mask"] if arrays["static_mask"].ndim == 4 else arrays["static_mask"][None]
        np.testing.assert_array_equal(demo.static_mask, expected != 0)


# --------------------------------------------------------------------------- reconstructions


@st.composite
def reconstruction_arrays(draw, mutate: bool = True):
    rng = rng_of(draw(st.integers(0, 2**32 - 1)))
    n, k = draw(st.integers(1, 4)), draw(st.integers(0, 2))
    arrays = valid_reconstruction_arrays(rng, n, k, draw(st.sampled_from(("", *ACTIONS))))
    if draw(st.booleans()):
        del arrays["action"]  # optional: unknown
    names = set()
    if mutate:
        for _ in range(draw(st.integers(1, 3))):
            names |= draw(reconstruction_mutation(arrays, rng, n, k))
    return arrays, names


@st.composite
def reconstruction_mutation(draw, arrays, rng, n, k):
    kind = draw(st.sampled_from(("drop", "extra", "replace", "replace", "special")))
    if kind == "drop":
        key = draw(st.sampled_from(sorted(arrays)))
        del arrays[key]
        return {key}
    if kind == "extra":
        key = draw(st.sampled_from(("hand_mask", "truth_fps", "Fps", "grasp_signal", "static", "x")))
        arrays[key] = np.zeros(2)
        return {key}
    key = draw(st.sampled_from(sorted(FIELD_SHAPES)))
    if kind == "special":
        arrays[key] = draw(st.sampled_from({
            "fps": (np.array(0.0), np.array(-12.0), np.array(np.nan), np.array([12.0])),
            "image_size": (np.array([24.0, 32.0]), np.array([0, 32]), np.array([-24, 32]), np.array([True, True]),
                           np.array([2**63 + 5, 32], dtype=np.uint64), np.array([24, 32, 3])),
            "action": (np.array("fly"), np.array(b"pick_up"), np.array(["pick_up"]), np.array(1.0)),
        }.get(key, (np.zeros((n + 1, 3)), np.zeros((k + 1, 3, 3)), np.zeros(())))))
        # A field of another N or K may be reported on the first field that disagrees with it.
        return {key, *(name for name, shape in FIELD_SHAPES.items() if "N" in shape or "K" in shape)}
    dims = {"N": n, "K": k}
    shape = tuple(dims.get(size, size) for size in FIELD_SHAPES[key])
    arrays[key] = bad_number_array(rng, shape, draw(st.sampled_from(BAD_HOWS)))
    return {key, *(name for name, shape in FIELD_SHAPES.items() if "N" in shape or "K" in shape)}


@fuzz(250)
@given(reconstruction_arrays())
def test_malformed_reconstruction_files_raise_reconstruction_error(case):
    CASES["reconstruction arrays"] += 1
    arrays, names = case
    buffer = io.BytesIO(npz_bytes(arrays))
    recon, error = outcome(lambda: Reconstruction.load(buffer), ReconstructionError, names)
    if error is None:
        check_reconstruction(recon)
    else:
        assert str(buffer) in str(error)


@st.composite
def replay_arrays(draw):
    arrays, names = draw(reconstruction_arrays(mutate=draw(st.booleans())))
    rng = rng_of(draw(st.integers(0, 2**32 - 1)))
    frames = draw(st.integers(1, 4))
    arrays.update(success=np.array(True), engine=np.array("mujoco"), replay_time=np.array(0.5),
                  joints=rng.normal(size=(frames, 7)))
    for _ in range(draw(st.integers(0, 2))):
        key = draw(st.sampled_from(("engine", "joints", "replay_time", "success")))
        value = draw(st.sampled_from({
            "engine": (None, np.array(3), np.array(["mujoco"]), np.array(b"mujoco"), np.array("newton")),
            "joints": (None, np.full((frames, 7), np.nan), np.zeros((frames, 6)), np.zeros(7), np.full((frames, 7), "a"),
                       np.zeros((frames, 7), dtype=complex), np.zeros((0, 7))),
            "replay_time": (None, np.array(np.nan), np.array(-1.0), np.array("1"), np.array([0.5, 0.5]), np.array(2)),
            "success": (None, np.array("yes"), np.array(False)),
        }[key]))
        if value is None:
            arrays.pop(key, None)
        else:
            arrays[key] = value
        names.add(key)
    return arrays, names | {"action", "static"}  # a put_* action needs a static object to be judged


def check_replay(replay: Replay) -> None:
    check_reconstruction(replay.reconstruction)
    assert isinstance(replay.engine, str)
    assert math.isfinite(replay.replay_time) and replay.replay_time >= 0
    assert replay.joints.ndim == 2 and replay.joints.shape[1] == 7 and np.isfinite(replay.joints).all()
    assert isinstance(replay.success, bool)


@fuzz(120)
@given(replay_arrays())
def test_malformed_replay_files_raise_reconstruction_error(case):
    CASES["replay arrays"] += 1
    arrays, names = case
    buffer = io.BytesIO(npz_bytes(arrays))
    replay, error = outcome(lambda: Replay.load(buffer), ReconstructionError, names | set(FIELD_SHAPES))
    if error is None:
        check_replay(replay)
    else:
        assert str(buffer) in str(error)


# --------------------------------------------------------------------------- corrupt bytes


def _patch_all(data: bytearray, signature: bytes, offset: int, value: int) -> bytes:
    """Set the 2-byte field at ``offset`` of every zip record starting with ``signature``."""
    start = data.find(signature)
    while start >= 0:
        data[start + offset : start + offset + 2] = value.to_bytes(2, "little")
        start = data.find(signature, start + 4)
    return bytes(data)


def _zip_with(members: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return buffer.getvalue()


def _npy(array: np.ndarray, allow_pickle: bool = False) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=allow_pickle)
    return buffer.getvalue()


@st.composite
def corrupt_npz(draw):
    """(loader, bytes): a valid file of that loader's kind, then damaged."""
    rng = rng_of(draw(st.integers(0, 2**32 - 1)))
    loader = draw(st.sampled_from(("demonstration", "reconstruction", "replay")))
    if loader == "demonstration":
        m = random_mask(rng, (2, 3, 4)).astype(np.uint8)
        arrays = {"hand_mask": m, "object_mask": m, "contact": np.array([1, 0]), "fps": np.array(12.0)}
    else:
        arrays = valid_reconstruction_arrays(rng, 2, 0)
        if loader == "replay":
            arrays.update(engine=np.array("mujoco"), joints=np.zeros((2, 7)), replay_time=np.array(1.0))
    data = bytearray(npz_bytes(arrays))
    how = draw(st.sampled_from(("truncate", "flip", "flip", "zero_run", "junk_prefix", "random", "empty", "npy",
                                "pickle", "raw_member", "garbage_member", "encrypted", "method", "text", "npy_truncated")))
    if how == "truncate":
        data = data[: draw(st.integers(0, len(data) - 1))]
    elif how == "flip":
        for _ in range(draw(st.integers(1, 8))):
            data[draw(st.integers(0, len(data) - 1))] ^= draw(st.integers(1, 255))
    elif how == "zero_run":
        start = draw(st.integers(0, len(data) - 1))
        data[start : start + draw(st.integers(1, 64))] = bytes(64)[: len(data[start : start + 64])]
    elif how == "junk_prefix":
        data = bytearray(rng.bytes(draw(st.integers(1, 64)))) + data
    elif how == "random":
        data = bytearray(rng.bytes(draw(st.integers(1, 300))))
    elif how == "empty":
        data = bytearray()
    elif how == "npy":
        data = bytearray(_npy(arrays["fps"]))
    elif how == "pickle":
        data = bytearray(_npy(np.array([{"fps": 1}], dtype=object), allow_pickle=True))
    elif how == "raw_member":  # a member without the .npy suffix: NumPy hands back its raw bytes
        key = draw(st.sampled_from(sorted(arrays)))
        members = {name + ".npy": _npy(value) for name, value in arrays.items() if name != key}
        data = bytearray(_zip_with({**members, key: b"pick_up"}))
    elif how == "garbage_member":
        key = draw(st.sampled_from(sorted(arrays)))
        members = {name + ".npy": _npy(value) for name, value in arrays.items()}
        members[key + ".npy"] = rng.bytes(draw(st.integers(0, 100)))
        data = bytearray(_zip_with(members))
    elif how == "npy_truncated":
        key = draw(st.sampled_from(sorted(arrays)))
        members = {name + ".npy": _npy(value) for name, value in arrays.items()}
        members[key + ".npy"] = members[key + ".npy"][: draw(st.integers(0, len(members[key + ".npy"]) - 1))]
        data = bytearray(_zip_with(members))
    elif how == "encrypted":
        data = bytearray(_patch_all(data, b"PK\x01\x02", 8, 1))
    elif how == "method":
        data = bytearray(_patch_all(data, b"PK\x01\x02", 10, draw(st.sampled_from((1, 6, 9, 12, 14, 99)))))
    elif how == "text":
        data = bytearray(draw(st.text(max_size=50)).encode())
    return loader, bytes(data)


@pytest.mark.slow
@fuzz(250)
@given(corrupt_npz())
def test_corrupt_npz_bytes_raise_the_loaders_error(case):
    CASES["corrupt npz"] += 1
    loader, data = case
    buffer = io.BytesIO(data)
    load, error_type, check = {
        "demonstration": (Demonstration.load, DemonstrationError, check_demonstration),
        "reconstruction": (Reconstruction.load, ReconstructionError, check_reconstruction),
        "replay": (Replay.load, ReconstructionError, check_replay),
    }[loader]
    result, error = outcome(lambda: load(buffer), error_type, {str(buffer)})
    if error is None:  # a flipped bit in a stored field's padding, say: still a valid file
        check(result)


# --------------------------------------------------------------------------- mask folders and label images


def _png(image: np.ndarray) -> bytes:
    ok, encoded = cv2.imencode(".png", image)
    assert ok
    return encoded.tobytes()


def _frame_masks(rng, n, h, w, empty=False):
    """(n, h, w) bool: one rectangle per frame (a blob, so clean-up keeps it)."""
    masks = np.zeros((n, h, w), dtype=bool)
    if not empty:
        for k in range(n):
            y, x = rng.integers(0, h), rng.integers(0, w)
            masks[k, y : y + int(rng.integers(1, h + 1)), x : x + int(rng.integers(1, w + 1))] = True
    return masks


def _mask_image(mask: np.ndarray, depth: str) -> np.ndarray:
    if depth == "u8_255":
        return mask.astype(np.uint8) * 255
    if depth == "u8_1":
        return mask.astype(np.uint8)
    if depth == "u16":
        return mask.astype(np.uint16) * 65535
    if depth == "bgr":
        return np.repeat(mask[..., None].astype(np.uint8) * 200, 3, axis=2)
    return np.concatenate([np.repeat(mask[..., None].astype(np.uint8) * 255, 3, axis=2),
                           np.full((*mask.shape, 1), 255, np.uint8)], axis=2)  # bgra


def _damage(draw, rng, files: dict[str, bytes | None], folders: list[str], h, w) -> set[str]:
    """Break a folder tree (relative path -> bytes; None = a directory) in one way; the names an error may cite."""
    image_paths = sorted(path for path, data in files.items() if data is not None and path.endswith(".png"))
    how = draw(st.sampled_from(("resize", "garbage", "truncate", "drop_frame", "empty_dir", "missing_dir", "extra_file",
                                "dir_as_png", "text_as_png", "upper_suffix")))
    path = draw(st.sampled_from(image_paths))
    folder = path.rsplit("/", 1)[0] if "/" in path else ""
    if how == "resize":
        files[path] = _png(np.full((h + draw(st.integers(1, 3)), w, 1), 255, np.uint8))
        return {path.rsplit("/", 1)[-1], folder}
    if how == "garbage":
        files[path] = rng.bytes(draw(st.integers(0, 200)))
        return {path}
    if how == "truncate":
        files[path] = files[path][: draw(st.integers(0, len(files[path]) - 1))]
        return {path}
    if how == "drop_frame":
        del files[path]
        return {""}  # the frame counts disagree: the message names the top folder
    if how == "empty_dir":
        for other in [p for p in files if p.startswith(folder + "/") or (not folder and "/" not in p)]:
            del files[other]
        files[folder or "."] = None
        return {folder or ""}
    if how == "missing_dir":
        for other in [p for p in files if p.startswith(folder + "/") or (not folder and "/" not in p)]:
            del files[other]
        return {folder or ""}
    if how == "extra_file":
        files[f"{folder}/notes.txt".lstrip("/")] = b"not an image"
        return set()
    if how == "dir_as_png":
        files[f"{folder}/zz_dir.png".lstrip("/")] = None
        return {"zz_dir.png"}
    if how == "text_as_png":
        files[f"{folder}/zz.png".lstrip("/")] = b"P1\n1 1\n1\n"
        return {"zz.png"}
    files[path[:-4] + ".PNG"] = files.pop(path)  # still read: suffixes are case-insensitive
    return set()


def _write_tree(root: Path, files: dict[str, bytes | None]) -> None:
    for rel, data in files.items():
        path = root / rel
        if data is None:
            path.mkdir(parents=True, exist_ok=True)
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)


@st.composite
def mask_folder_trees(draw):
    rng = rng_of(draw(st.integers(0, 2**32 - 1)))
    n, h, w = draw(st.integers(1, 4)), draw(st.integers(2, 8)), draw(st.integers(2, 8))
    objects = ["hand", "object", *draw(st.sampled_from(([], ["static"], ["static_0", "static_1"])))]
    files: dict[str, bytes | None] = {}
    for name in objects:
        masks = _frame_masks(rng, n, h, w, empty=draw(st.integers(0, 9)) == 0)
        depth = draw(st.sampled_from(("u8_255", "u8_1", "u16", "bgr", "bgra")))
        for k, mask in enumerate(masks):
            files[f"{name}/{k:05d}.png"] = _png(_mask_image(mask, depth))
    names: set[str] = set()
    for _ in range(draw(st.integers(0, 2))):
        if any(data is not None for data in files.values()):
            names |= _damage(draw, rng, files, objects, h, w)
    contact = draw(st.sampled_from((None, "ones", "short", "zeros", "255")))
    contact = {None: None, "ones": np.ones(n), "short": np.ones(n + 1), "zeros": np.zeros(n), "255": np.full(n, 255)}[contact]
    fps = draw(st.sampled_from((12.0, 30, np.nan, -1.0, 0.0, np.inf)))
    return files, names, contact, fps


def _reader_names(root: Path, names: set[str]) -> set[str]:
    """What a reader's error may name: a damaged file or folder (under ``root``), or a demonstration key."""
    return {str(root / name) if "/" in name or name == "" else name for name in names} | {str(root)} | set(DEMO_KEYS)


def check_reader(folder: str, files: dict[str, bytes | None], names: set[str], read) -> None:
    """Write ``files`` into a fresh ``folder`` and ``read(root)`` it: a valid demonstration, or an
    error that names the folder, one of ``names`` or a demonstration key."""
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / folder
        root.mkdir()
        _write_tree(root, files)
        demo, error = outcome(lambda: read(root), (DemonstrationError, FileNotFoundError), _reader_names(root, names))
    if error is None:
        check_demonstration(demo)


@pytest.mark.slow
@fuzz(150)
@given(mask_folder_trees())
def test_malformed_mask_folders_raise_demonstration_error(case):
    CASES["mask folders"] += 1
    files, names, contact, fps = case
    check_reader("masks", files, names, lambda root: read_mask_folders(root, fps, contact=contact))


@st.composite
def label_image_folders(draw):
    rng = rng_of(draw(st.integers(0, 2**32 - 1)))
    n, h, w = draw(st.integers(1, 4)), draw(st.integers(2, 8)), draw(st.integers(2, 8))
    labels = np.zeros((n, h, w), dtype=np.uint8)
    for index in draw(st.lists(st.integers(1, 5), min_size=0, max_size=4)):
        labels[_frame_masks(rng, n, h, w)] = index
    style = draw(st.sampled_from(("index", "index16", "davis", "custom")))
    mapping = None
    if style == "index":
        images = labels
    elif style == "index16":
        images = labels.astype(np.uint16) * draw(st.sampled_from((1, 300)))
    else:
        palette = davis_palette(6) if style == "davis" else rng.integers(0, 256, (6, 3)).astype(np.uint8)
        palette[0] = 0
        images = palette[labels][..., ::-1]
        if style == "custom":
            mapping = {"hand": tuple(int(v) for v in palette[1]), "object": tuple(int(v) for v in palette[2]),
                       "static": [tuple(int(v) for v in palette[3])]}
    files: dict[str, bytes | None] = {f"{k:05d}.png": _png(image) for k, image in enumerate(images)}
    names: set[str] = set()
    for _ in range(draw(st.integers(0, 2))):
        how = draw(st.sampled_from(("file", "file", "mix", "mapping")))
        if how == "file" and any(data is not None for data in files.values()):
            names |= _damage(draw, rng, files, [], h, w)
        elif how == "mix":  # one colour image among index images, or the reverse
            pngs = sorted(name for name, data in files.items() if data is not None and name.endswith(".png"))
            if not pngs:
                continue
            name = draw(st.sampled_from(pngs))
            files[name] = _png(np.zeros((h, w, 3), np.uint8) if images.ndim == 3 else np.zeros((h, w), np.uint8))
            names |= {""}
        else:
            mapping = draw(st.sampled_from((
                {"hand": 1}, {"hand": 1, "object": 2, "arm": 3}, {"hand": (1, 0, 0), "object": (0, 1, 0)},
                {"hand": 1, "object": 2}, {"hand": 1, "object": 2, "static": [3, 4, 5]}, {"hand": 1, "object": 2, "static": 3},
                {"hand": [1], "object": 2}, {"hand": None, "object": 2},
            )))
            names |= {""}
    contact = draw(st.sampled_from((None, np.ones(n), np.ones(n + 2))))
    return files, names, mapping, contact


@fuzz(150)
@given(label_image_folders())
def test_malformed_label_images_raise_demonstration_error(case):
    CASES["label images"] += 1
    files, names, mapping, contact = case
    check_reader("labels", files, names, lambda root: read_label_images(root, 12.0, mapping=mapping, contact=contact))


# --------------------------------------------------------------------------- Something-Else JSON and CSVs

SE_IMAGE = (24, 32)
JUNK = st.one_of(
    st.none(), st.booleans(), st.integers(-5, 40), st.floats(allow_nan=True, allow_infinity=True),
    st.text("abc 0123456789-/.", max_size=8), st.lists(st.integers(0, 3), max_size=3), st.just({}),
    st.just({"x1": 1}),
)


def _se_label(rng, name, category):
    x1, y1 = rng.uniform(-5, 30), rng.uniform(-5, 22)
    return {"box2d": {"x1": x1, "y1": y1, "x2": x1 + rng.uniform(-2, 15), "y2": y1 + rng.uniform(-2, 12)},
            "category": category, "gt_annotation": name}


def _mutate_json(draw, rng, node):
    """Replace, delete or retype one node of a JSON tree (in place where possible); returns the new tree."""
    path = []
    while isinstance(node if not path else path[-1][0][path[-1][1]], (dict, list)) and draw(st.integers(0, 3)):
        current = node if not path else path[-1][0][path[-1][1]]
        if not current:
            break
        key = draw(st.sampled_from(sorted(current) if isinstance(current, dict) else list(range(len(current)))))
        path.append((current, key))
    if not path:
        return draw(JUNK)
    parent, key = path[-1]
    if draw(st.booleans()) and isinstance(parent, dict) or isinstance(parent, list) and draw(st.booleans()):
        del parent[key]
    else:
        parent[key] = draw(JUNK)
    return node


def _phase_text(draw):
    return draw(st.one_of(
        st.builds(lambda a, d: f"{a}-{a + d}", st.integers(1, 10), st.integers(0, 6)),
        st.sampled_from(("-", "", "0-3", "5-2", "a-b", "1-", "3", " 2-4 ", "1-2-3", "١-٣", "nan-4", "-1-3")),
    ))


@st.composite
def something_else_files(draw):
    rng = rng_of(draw(st.integers(0, 2**32 - 1)))
    videos = draw(st.lists(st.sampled_from(("7", "12", "301", "x")), min_size=1, max_size=3, unique=True))
    boxes = {}
    for vid in videos:
        entries = []
        for frame in draw(st.lists(st.integers(1, 12), max_size=8, unique=True)):
            labels = [_se_label(rng, "object hand", "hand"), _se_label(rng, "object 0", "cup")]
            labels += [_se_label(rng, name, cat) for name, cat in
                       draw(st.lists(st.sampled_from((("object 1", "box"), ("object x", "cup"), ("obj", "lamp"),
                                                      ("object hand", "hand"), ("hand", "hand"))), max_size=2))]
            entries.append({"name": f"{vid}/{frame:04d}.jpg", "labels": labels, "gt_placeholders": ["cup", "box"]})
        boxes[vid] = entries
    for _ in range(draw(st.integers(0, 3))):
        how = draw(st.sampled_from(("tree", "tree", "box", "name", "empty")))
        vid = draw(st.sampled_from(videos))
        if how == "tree":
            boxes = _mutate_json(draw, rng, boxes)
        elif how in ("box", "name") and isinstance(boxes, dict) and boxes.get(vid):
            try:  # an earlier tree mutation may have broken the path to the box or the name
                if how == "box":
                    label = boxes[vid][0]["labels"][draw(st.integers(0, 1))]
                    coordinate = draw(st.sampled_from(("x1", "y1", "x2", "y2")))
                    value = draw(st.sampled_from((math.nan, math.inf, -math.inf, -50.0, 1e9, "12", None, [1])))
                    label["box2d"][coordinate] = value
                else:
                    names = (f"{vid}/0000.jpg", "abc", f"{vid}/12", 12, None, "0.jpg", "-3.jpg")
                    boxes[vid][0]["name"] = draw(st.sampled_from(names))
            except (KeyError, TypeError, IndexError):
                pass
        elif how == "empty" and isinstance(boxes, dict):
            boxes[vid] = draw(st.sampled_from(([], [{}], [{"name": "7/0001.jpg", "labels": []}], {}, "frames")))
    text = json.dumps(boxes).encode()
    if draw(st.integers(0, 5)) == 0:
        text = draw(st.sampled_from((text[: len(text) // 2], b"\xff\xfe" + text, b"\xef\xbb\xbf" + text, b"", b"[]",
                                     text.replace(b"{", b"[", 1), b"\x00")))
    header = ["video_id", "action_id", "approach", "action", "leave"]
    rows = [[vid, "1", _phase_text(draw), _phase_text(draw), _phase_text(draw)] for vid in videos]
    action_rows = [[vid, draw(st.sampled_from((*ACTIONS, "fly", "", " pick_up", "PICK_UP")))] for vid in videos]
    for _ in range(draw(st.integers(0, 2))):
        how = draw(st.sampled_from(("drop_col", "short_row", "long_row", "dup", "short_action", "bad_bytes")))
        if how == "drop_col":
            column = draw(st.sampled_from(range(len(header))))
            header = header[:column] + header[column + 1 :]
        elif how == "short_row" and rows:
            rows[0] = rows[0][: draw(st.integers(0, 4))]
        elif how == "long_row" and rows:
            rows[0] = rows[0] + ["9-9"]
        elif how == "dup" and rows:
            rows.append(list(rows[0]))
        elif how == "short_action" and action_rows:
            action_rows[0] = action_rows[0][:1]
        elif how == "bad_bytes" and rows:
            rows[0][0] = "\udcff"  # an undecodable byte once written with surrogateescape
    with_actions = draw(st.booleans())
    return text, _csv_bytes(header, rows), _csv_bytes(["video_id", "action"], action_rows) if with_actions else None


def _csv_bytes(header, rows) -> bytes:
    buffer = io.StringIO()
    writer = csv.writer(buffer)
    writer.writerow(header)
    writer.writerows(rows)
    return buffer.getvalue().encode("utf-8", "surrogateescape")


@pytest.mark.slow
@fuzz(200)
@given(something_else_files())
def test_malformed_something_else_files_raise_demonstration_error(case):
    CASES["something-else"] += 1
    annotations, phases, actions = case
    with tempfile.TemporaryDirectory() as tmp:
        paths = [Path(tmp) / "a.json", Path(tmp) / "p.csv", Path(tmp) / "x.csv"]
        paths[0].write_bytes(annotations)
        paths[1].write_bytes(phases)
        if actions is not None:
            paths[2].write_bytes(actions)
        files = {str(path) for path in paths}
        videos, error = outcome(lambda: read_something_else(paths[0], paths[1], paths[2] if actions else None),
                                DemonstrationError, files)
    for video in (videos or {}).values():
        result, error = outcome(lambda video=video: something_else_demonstration(video, image_size=SE_IMAGE),
                                DemonstrationError, {f"video {video.video_id}"})
        if error is None:
            demo, notes = result
            check_demonstration(demo)
            assert demo.image_size == SE_IMAGE and all(isinstance(note, str) for note in notes)


# --------------------------------------------------------------------------- detections CSV


@st.composite
def detections_files(draw):
    n = draw(st.integers(1, 6))
    header = draw(st.sampled_from((["frame", "in_contact"], ["frame", "in_contact", "score"], ["frame", "contact"],
                                   ["in_contact", "frame", "score"], [], ["Frame", "in_contact"])))
    value = {
        "frame": st.one_of(st.integers(-2, n + 2).map(str), st.sampled_from(("", "1.0", "x", " 2 ", "1e3", "nan"))),
        "in_contact": st.sampled_from(("0", "1", "true", "False", "TRUE", "", "2", "yes", "0.0", "-1")),
        "score": st.one_of(st.floats(-1, 2).map(str), st.sampled_from(("", "nan", "inf", "-inf", "high", "1,0"))),
    }
    rows = []
    for _ in range(draw(st.integers(0, n + 2))):
        row = [draw(value.get(column, st.just("1"))) for column in header]
        rows.append(row[: draw(st.integers(0, len(row)))] if draw(st.integers(0, 9)) == 0 else row)
    data = _csv_bytes(header, rows)
    if draw(st.integers(0, 9)) == 0:
        data = draw(st.sampled_from((b"\xff\xfe" + data, data + b"\x00", b"", b'frame,in_contact\n"1,1\n')))
    return data, n


@fuzz(200)
@given(detections_files())
def test_malformed_detections_raise_demonstration_error(case):
    CASES["detections"] += 1
    data, n = case
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "detections.csv"
        path.write_bytes(data)
        detections, error = outcome(lambda: read_detections(path, n), DemonstrationError, {str(path)})
    if error is None:
        assert detections.shape == (n,) and detections.dtype == np.int8
        assert np.isin(detections, (UNKNOWN, NO_CONTACT, IN_CONTACT)).all()


# --------------------------------------------------------------------------- regressions of the bugs found


def test_npz_member_without_npy_suffix_is_a_demonstration_error():
    """NumPy returns such a member's raw bytes; the action check used to crash on ``bytes.dtype``."""
    m = np.ones((1, 2, 2), np.uint8)
    members = {f"{k}.npy": _npy(v) for k, v in {"hand_mask": m, "object_mask": m, "contact": np.ones(1),
                                                 "fps": np.array(12.0)}.items()}
    buffer = io.BytesIO(_zip_with({**members, "action": b"pick_up"}))
    with pytest.raises(DemonstrationError, match="action: not a NumPy array"):
        Demonstration.load(buffer)


@pytest.mark.parametrize("offset, value, what", [(8, 1, "encrypted"), (10, 99, "compression method")])
def test_encrypted_or_unknown_compression_npz_is_a_reconstruction_error(offset, value, what):
    data = _patch_all(bytearray(npz_bytes(valid_reconstruction_arrays(rng_of(0), 2, 0))), b"PK\x01\x02", offset, value)
    with pytest.raises(ReconstructionError, match="not a readable .npz archive|unreadable"):
        Reconstruction.load(io.BytesIO(data))


def test_zero_frame_reconstruction_is_rejected():
    arrays = valid_reconstruction_arrays(rng_of(0), 0, 0)
    with pytest.raises(ReconstructionError, match="t: expected at least one frame"):
        Reconstruction.load(io.BytesIO(npz_bytes(arrays)))


@pytest.mark.parametrize(
    "key, value, match",
    [
        ("joints", np.full((2, 7), "a"), "joints"),
        ("joints", np.full((2, 7), np.nan), "joints"),
        ("joints", np.zeros((2, 6)), "joints"),
        ("replay_time", np.array("1"), "replay_time"),
        ("replay_time", np.array([1.0, 2.0]), "replay_time"),
        ("replay_time", np.array(np.nan), "replay_time"),
        ("replay_time", None, "replay_time"),
        ("engine", np.array(3), "engine"),
        ("fps", None, "fps"),
        ("action", np.array("put_onto"), "put_onto"),  # needs a static object, this scene has none
    ],
)
def test_malformed_replay_keys_are_reconstruction_errors(key, value, match):
    arrays = valid_reconstruction_arrays(rng_of(0), 2, 0)
    arrays.update(engine=np.array("mujoco"), joints=np.zeros((2, 7)), replay_time=np.array(1.0))
    if value is None:
        del arrays[key]
    else:
        arrays[key] = value
    with pytest.raises(ReconstructionError, match=match):
        Replay.load(io.BytesIO(npz_bytes(arrays)))


def _something_else(tmp_path, annotations: bytes, phases: bytes, actions: bytes | None = None):
    (tmp_path / "a.json").write_bytes(annotations)
    (tmp_path / "p.csv").write_bytes(phases)
    if actions is not None:
        (tmp_path / "x.csv").write_bytes(actions)
    return read_something_else(tmp_path / "a.json", tmp_path / "p.csv", tmp_path / "x.csv" if actions else None)


def test_something_else_undecodable_or_short_files_are_demonstration_errors(tmp_path):
    phases = b"video_id,approach,action,leave\n7,1-2,3-4,-\n"
    with pytest.raises(DemonstrationError, match=r"a\.json: not UTF-8 text"):
        _something_else(tmp_path, b"\xff\xfe{}", phases)
    with pytest.raises(DemonstrationError, match=r"p\.csv: not UTF-8 text"):
        _something_else(tmp_path, b"{}", b"video_id,approach,action,leave\n\xff,1-2,3-4,-\n")
    with pytest.raises(DemonstrationError, match=r"x\.csv, line 2: unknown action ''"):
        _something_else(tmp_path, b"{}", phases, b"video_id,action\n7\n")


def _se_video(tmp_path, name: str, box: dict):
    label = {"box2d": box, "category": "hand", "gt_annotation": "object hand"}
    obj = {"box2d": {"x1": 2, "y1": 2, "x2": 9, "y2": 9}, "category": "cup", "gt_annotation": "object 0"}
    entries = [{"name": name, "labels": [label, obj], "gt_placeholders": ["cup"]}]
    return _something_else(tmp_path, json.dumps({"7": entries}).encode(), b"video_id,approach,action,leave\n7,-,1-2,-\n")["7"]


def test_something_else_frame_numbers_are_one_based(tmp_path):
    """Frame 0000 used to land silently in the last frame (index -1)."""
    video = _se_video(tmp_path, "7/0000.jpg", {"x1": 1, "y1": 1, "x2": 9, "y2": 9})
    with pytest.raises(DemonstrationError, match="video 7: frame entry 0: frame number 0"):
        something_else_demonstration(video, image_size=SE_IMAGE)


def test_something_else_nan_boxes_are_dropped_with_a_note(tmp_path):
    video = _se_video(tmp_path, "7/0001.jpg", {"x1": 1, "y1": float("nan"), "x2": 9, "y2": 9})
    with pytest.raises(DemonstrationError, match="video 7: hand_mask: empty in every frame"):
        something_else_demonstration(video, image_size=SE_IMAGE)
    video.frames.append({**video.frames[0], "name": "7/0002.jpg"})
    video.frames[1]["labels"] = [{**video.frames[0]["labels"][0], "box2d": {"x1": 1, "y1": 1, "x2": 9, "y2": 9}}]
    demo, notes = something_else_demonstration(video, image_size=SE_IMAGE)
    assert not demo.hand_mask[0].any() and demo.hand_mask[1].any()
    assert any("hand: dropped empty, non-finite or out-of-image boxes in frame(s) 1" in note for note in notes)


@pytest.mark.parametrize(
    "content, match",
    [
        (b"frame,in_contact\n\xff1,1\n", "not UTF-8 text"),
        (b"frame,in_contact,score\n1,1,nan\n", "score.*finite"),
        (b"frame,in_contact\n1,1\x00\n", "detections.csv"),
    ],
)
def test_detections_csv_errors_are_demonstration_errors(tmp_path, content, match):
    path = tmp_path / "detections.csv"
    path.write_bytes(content)
    with pytest.raises(DemonstrationError, match=match):
        read_detections(path, 3)


@pytest.mark.parametrize("value", [[1], (1, 2), None])
def test_label_mapping_with_a_non_integer_index_is_a_demonstration_error(tmp_path, value):
    labels = np.zeros((1, 4, 4), np.uint8)
    labels[0, :2], labels[0, 2:] = 1, 2
    cv2.imwrite(str(tmp_path / "00000.png"), labels[0])
    with pytest.raises(DemonstrationError, match="hand"):
        read_label_images(tmp_path, 12.0, mapping={"hand": value, "object": 2}, contact=np.ones(1))


def test_majority_filter_of_a_video_shorter_than_its_window(tmp_path):
    """np.convolve(mode="same") returned max(N, window) votes: a 1-frame mask folder crashed the contact filter."""
    from warpskill.contract.signals import majority_filter

    assert majority_filter(np.array([True])).tolist() == [True]
    assert majority_filter(np.array([True, False, True])).tolist() == [True, True, True]
    mask = np.zeros((4, 4), np.uint8)
    mask[1:3, 1:3] = 255
    for name in ("hand", "object"):
        (tmp_path / name).mkdir()
        cv2.imwrite(str(tmp_path / name / "00000.png"), mask)
    demo = read_mask_folders(tmp_path, 12.0)
    assert demo.num_frames == 1 and demo.contact.tolist() == [True]


def test_zz_enough_cases_were_generated():
    """Runs last (file order): the properties above ran at least MIN_CASES cases together."""
    properties = 9
    if len(CASES) < properties:
        pytest.skip(f"only {len(CASES)} of the {properties} properties ran in this session")
    total = sum(CASES.values())
    print(f"\nfuzz cases: {total} ({dict(CASES)})")
    assert total >= MIN_CASES, dict(CASES)
