"""The replay file of the contract: the simulated scene in reconstruction keys, read back whole."""

from __future__ import annotations

import numpy as np
import pytest

from warpskill.contract.evaluation import evaluate
from warpskill.contract.reconstruction import Reconstruction, ReconstructionError
from warpskill.contract.replay import Replay


def _scene(n: int = 8) -> Reconstruction:
    t = np.arange(n) / 10.0
    eye = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    lift = np.clip(t - 0.3, 0.0, None)
    return Reconstruction(
        fps=np.array(10.0),
        t=t,
        hand_pos=np.stack([np.zeros(n), np.full(n, 0.5), 0.08 + lift], -1),
        hand_rot=eye,
        grasp=np.full(n, 0.02),
        grasped=np.ones(n),
        object_pos=np.stack([np.zeros(n), np.full(n, 0.5), 0.04 + lift], -1),
        object_rot=eye,
        object_size=np.array([0.06, 0.05, 0.08]),
        static_pos=np.zeros((0, 3)),
        static_rot=np.zeros((0, 3, 3)),
        static_size=np.zeros((0, 3)),
        camera_K=np.array([[100.0, 0, 64], [0, 100.0, 48], [0, 0, 1]]),
        camera_elevation=np.array(0.5),
        camera_height=np.array(0.4),
        image_size=np.array([96, 128]),
        action="pick_up",
        loss=np.array(0.0),
    )


def test_replay_round_trips_through_its_file(tmp_path):
    scene = _scene()
    joints = np.linspace(0.0, 1.0, 8 * 7).reshape(8, 7)
    replay = Replay(scene, evaluate(scene, "pick_up"), "mujoco", 0.25, joints)
    replay.save(tmp_path / "replay.npz")

    loaded = Replay.load(tmp_path / "replay.npz")
    assert loaded.engine == "mujoco" and loaded.replay_time == pytest.approx(0.25)
    np.testing.assert_array_equal(loaded.joints, joints)
    for name in ("hand_pos", "object_pos", "object_rot", "object_size", "grasped", "camera_K"):
        np.testing.assert_array_equal(getattr(loaded.reconstruction, name), getattr(scene, name))
    assert loaded.success == replay.success
    assert loaded.evaluation.checks == replay.evaluation.checks


def test_a_reconstruction_is_not_a_replay(tmp_path):
    _scene().save(tmp_path / "reconstruction.npz")
    with pytest.raises(ReconstructionError, match="not a replay file.*engine"):
        Replay.load(tmp_path / "reconstruction.npz")


def test_a_corrupt_replay_file_names_itself(tmp_path):
    path = tmp_path / "replay.npz"
    path.write_bytes(b"not a zip archive")
    with pytest.raises(ReconstructionError, match="replay.npz"):
        Replay.load(path)
