"""Tests for warpskill.contract.reconstruction: the reconstruction file of docs/formats.md."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from record_support import assert_save_is_atomic

from warpskill.contract.reconstruction import (
    FIELD_SHAPES,
    Reconstruction,
    ReconstructionError,
)

N, K = 5, 2


def rotation_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


JUDGED = [{"start": "stage (a)", "contact_frames": 3, "fit": 2.8, "ends_behind_static": True, "contradicted": False,
           "chosen": False},
          {"start": "on the static", "contact_frames": 3, "fit": 2.6, "ends_behind_static": False,
           "contradicted": False, "chosen": True}]


def valid_fields(num_static: int = K) -> dict[str, np.ndarray]:
    """A small valid reconstruction, as float32 arrays where the optimiser would give them."""
    rng = np.random.default_rng(0)
    f32 = np.float32
    return {
        "fps": np.array(12.0),
        "t": np.arange(N) / 12.0,
        "hand_pos": rng.normal(size=(N, 3)).astype(f32),
        "hand_rot": np.stack([rotation_z(0.1 * k) for k in range(N)]).astype(f32),
        "grasp": rng.normal(size=N).astype(f32),
        "grasped": np.array([0, 0, 1, 1, 0], f32),
        "object_pos": rng.normal(size=(N, 3)).astype(f32),
        "object_rot": np.stack([rotation_z(-0.2 * k) for k in range(N)]),
        "object_size": np.array([0.1, 0.2, 0.3]),
        "static_pos": np.tile([0.0, 0.5, 0.05], (num_static, 1)),
        "static_rot": np.tile(rotation_z(0.3), (num_static, 1, 1)),
        "static_size": np.tile([0.2, 0.2, 0.1], (num_static, 1)),
        "camera_K": np.array([[7.0, 0.0, 4.0], [0.0, 6.0, 3.0], [0.0, 0.0, 1.0]]),
        "camera_elevation": np.array(0.4),
        "camera_height": np.array(0.5),
        "image_size": np.array([6, 8]),
        "action": np.array("put_onto"),
        "loss": np.array(0.25),
        "options": np.array('{"seed": 0}'),
        "object_noun": np.array("mug"),
        "hypotheses": np.array(json.dumps(JUDGED)),
    }


def test_fields_are_the_format_keys():
    assert list(FIELD_SHAPES) == list(valid_fields())


@pytest.mark.parametrize("num_static", [K, 0])
def test_round_trip(num_static, tmp_path):
    fields = valid_fields(num_static)
    recon = Reconstruction(**fields)
    assert (recon.num_frames, recon.num_static) == (N, num_static)
    assert recon.hand_pos.dtype == np.float64 and recon.image_size.dtype == np.int64
    path = tmp_path / "reconstruction.npz"
    recon.save(path)
    with np.load(path) as saved:
        assert sorted(saved.files) == sorted(FIELD_SHAPES)
    loaded = Reconstruction.load(path)
    for name in FIELD_SHAPES:
        np.testing.assert_array_equal(getattr(loaded, name), fields[name])
    assert str(loaded.action) == "put_onto"


def test_the_hypotheses_record_reads_back_and_is_left_out_when_empty(tmp_path):
    recon = Reconstruction(**valid_fields())
    assert recon.judgements() == JUDGED
    with pytest.raises(ReconstructionError, match="hypotheses: expected a JSON list of objects"):
        Reconstruction(**{**valid_fields(), "hypotheses": np.array('{"start": "stage (a)"}')})
    path = tmp_path / "reconstruction.npz"
    Reconstruction(**{**valid_fields(), "hypotheses": np.array("")}).save(path)
    with np.load(path) as saved:
        assert "hypotheses" not in saved.files  # written as before the key
    assert Reconstruction.load(path).judgements() == []


def test_unknown_action_is_empty_string(tmp_path):
    assert str(Reconstruction(**{**valid_fields(), "action": None}).action) == ""
    fields = valid_fields()
    del fields["action"]
    path = tmp_path / "reconstruction.npz"
    np.savez_compressed(path, **fields)
    assert str(Reconstruction.load(path).action) == ""


BAD_FIELDS = {
    "hand_rot": (np.zeros((N, 3)), "expected shape (N, 3, 3)"),
    "grasp": (np.zeros(N + 1), "N = 5 (from t)"),
    "static_size": (np.zeros((K + 1, 3)), "K = 2 (from static_pos)"),
    "object_size": (np.array([0.1, np.nan, 0.1]), "NaN"),
    "object_pos": (np.full((N, 3), np.inf), "NaN or inf"),
    "camera_height": (np.array("high"), "expected numbers"),
    "fps": (np.array(0.0), "> 0"),
    "image_size": (np.array([6.0, 8.0]), "integers"),
    "loss": (np.array([0.25]), "expected shape ()"),
    "action": (np.array("throw"), "unknown action"),
    "hypotheses": (np.array("[{\"start\": "), "not JSON"),
}


@pytest.mark.parametrize("key", BAD_FIELDS)
def test_bad_field_names_key(key, tmp_path):
    value, problem = BAD_FIELDS[key]
    fields = {**valid_fields(), key: value}
    with pytest.raises(ReconstructionError) as error:
        Reconstruction(**fields)
    assert str(error.value).startswith(f"{key}: ") and problem in str(error.value)
    path = tmp_path / "reconstruction.npz"
    np.savez_compressed(path, **fields)
    with pytest.raises(ReconstructionError) as error:
        Reconstruction.load(path)
    assert str(error.value).startswith(f"{path}: {key}: ") and problem in str(error.value)


def test_image_size_must_be_positive():
    with pytest.raises(ReconstructionError, match="image_size: must be positive"):
        Reconstruction(**{**valid_fields(), "image_size": np.array([0, 8])})


@pytest.mark.parametrize("key", ["t", "object_rot", "camera_K"])
def test_missing_key(key, tmp_path):
    fields = valid_fields()
    del fields[key]
    path = tmp_path / "reconstruction.npz"
    np.savez_compressed(path, **fields)
    with pytest.raises(ReconstructionError, match=f"missing key.*{key}"):
        Reconstruction.load(path)


def test_unknown_key(tmp_path):
    path = tmp_path / "reconstruction.npz"
    np.savez_compressed(path, **valid_fields(), hand_velocity=np.zeros((N, 3)))
    with pytest.raises(ReconstructionError, match="unknown key.*hand_velocity"):
        Reconstruction.load(path)


def test_corrupt_file(tmp_path):
    path = tmp_path / "reconstruction.npz"
    Reconstruction(**valid_fields()).save(path)
    path.write_bytes(path.read_bytes()[:100])
    with pytest.raises(ReconstructionError, match="not a readable .npz"):
        Reconstruction.load(path)


def test_atomic_save_keeps_existing_file(tmp_path):
    recon = Reconstruction(**valid_fields())
    assert_save_is_atomic(recon, tmp_path / "reconstruction.npz",
                          lambda: setattr(recon, "loss", np.array([lambda: None], dtype=object)))


def test_object_corners():
    fields = valid_fields()
    recon = Reconstruction(**fields)
    corners = recon.object_corners()
    assert corners.shape == (N, 8, 3)
    # In the object's own frame the corners are the sign patterns of half the size.
    local = np.einsum("nji,nkj->nki", recon.object_rot, corners - recon.object_pos[:, None])
    half = recon.object_size / 2
    for frame in local:
        assert sorted(map(tuple, np.round(frame / half))) == sorted(
            (x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)
        )


def test_static_corners():
    recon = Reconstruction(**valid_fields())
    corners = recon.static_corners()
    assert corners.shape == (K, 8, 3)
    np.testing.assert_allclose(corners[0, :, 2].min(), 0.0, atol=1e-12)  # resting on the ground
    np.testing.assert_allclose(corners[0, :, 2].max(), 0.1)
    np.testing.assert_allclose(corners[0].mean(axis=0), [0.0, 0.5, 0.05], atol=1e-12)
    # Rotated by 0.3 rad about z, so the xy bounds are wider than the 0.2 m edge.
    width = corners[0, :, 0].max() - corners[0, :, 0].min()
    np.testing.assert_allclose(width, 0.2 * (math.cos(0.3) + math.sin(0.3)))
    assert Reconstruction(**valid_fields(0)).static_corners().shape == (0, 8, 3)
