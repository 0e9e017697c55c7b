"""The LeRobot v3.0 dataset: written by warpskill.export, read back with pyarrow, json and PyAV."""

from __future__ import annotations

import json
import subprocess
import sys

import av
import numpy as np
import pyarrow.parquet as pq
import pytest

from warpskill.export.lerobot import CODEBASE_VERSION, LeRobotError, LeRobotWriter, feature_stats
from warpskill.robot.video import prefer_headless_gl

prefer_headless_gl()  # before MuJoCo is first imported: its GL backend is chosen then

CAMERA = "observation.images.front"
NAMES = ["j1", "j2", "gripper"]


def read_dataset(root):
    """info, stats, data rows, episode rows, tasks and the decoded frames' times [s] of every camera."""
    info = json.loads((root / "meta/info.json").read_text())
    stats = json.loads((root / "meta/stats.json").read_text())
    data = pq.read_table(root / info["data_path"].format(chunk_index=0, file_index=0)).to_pydict()
    episodes = pq.read_table(root / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    tasks = pq.read_table(root / "meta/tasks.parquet")
    times = {}
    for key, feature in info["features"].items():
        if feature["dtype"] == "video":
            path = root / info["video_path"].format(video_key=key, chunk_index=0, file_index=0)
            with av.open(str(path)) as container:
                times[key] = [float(frame.pts * frame.time_base) for frame in container.decode(video=0)]
    return info, stats, data, episodes, tasks, times


def check_dataset(root, lengths, task):
    """The format's required fields and their consistency, for episodes of ``lengths`` frames of ``task``."""
    info, stats, data, episodes, tasks, times = read_dataset(root)
    assert info["codebase_version"] == CODEBASE_VERSION == "v3.0"
    assert isinstance(info["fps"], int) and info["fps"] > 0
    assert info["total_episodes"] == len(lengths) and info["total_frames"] == sum(lengths)
    assert info["total_tasks"] == 1 and info["splits"] == {"train": f"0:{len(lengths)}"}
    assert info["chunks_size"] > 0 and "{chunk_index:03d}" in info["data_path"] and "{video_key}" in info["video_path"]
    for name in ("timestamp", "frame_index", "episode_index", "index", "task_index"):
        assert info["features"][name]["shape"] == [1] and name in data
    for key, feature in info["features"].items():
        assert {"dtype", "shape", "names"} <= set(feature) and key in stats
        assert {"min", "max", "mean", "std", "count"} <= set(stats[key])
    assert tasks.column("task").to_pylist() == [task] and tasks.column("task_index").to_pylist() == [0]
    assert tasks.schema.pandas_metadata["index_columns"] == ["task"]
    fps = info["fps"]
    assert data["index"] == list(range(sum(lengths)))
    assert data["task_index"] == [0] * sum(lengths)
    for e, (episode, length) in enumerate(zip(episodes, lengths)):
        rows = slice(episode["dataset_from_index"], episode["dataset_to_index"])
        assert episode["episode_index"] == e and episode["length"] == length and episode["tasks"] == [task]
        assert data["episode_index"][rows] == [e] * length and data["frame_index"][rows] == list(range(length))
        np.testing.assert_allclose(data["timestamp"][rows], np.arange(length) / fps, atol=1e-6)
        for key, decoded in times.items():  # the episode's video span holds exactly its rows, at k / fps
            start, stop = episode[f"videos/{key}/from_timestamp"], episode[f"videos/{key}/to_timestamp"]
            inside = [t for t in decoded if start - 1e-4 <= t < stop - 1e-4]
            assert len(inside) == length
            np.testing.assert_allclose(inside, start + np.arange(length) / fps, atol=1e-4)
    for key, decoded in times.items():
        assert len(decoded) == info["total_frames"]
        assert np.shape(stats[key]["mean"]) == (3, 1, 1)
        assert 0.0 <= np.min(stats[key]["min"]) and np.max(stats[key]["max"]) <= 1.0
        assert info["features"][key]["info"]["video.codec"] == "h264"
    return info, stats, data


def test_writer_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    lengths = [5, 9]
    states = [rng.normal(size=(n, 3)) for n in lengths]
    root = tmp_path / "dataset"
    with LeRobotWriter(root, fps=10, vectors={"observation.state": NAMES, "action": NAMES},
                       cameras={CAMERA: (32, 48)}) as writer:
        for state in states:
            frames = rng.integers(0, 256, (len(state), 32, 48, 3), dtype=np.uint8)
            writer.add_episode({"observation.state": state, "action": state + 1.0}, {CAMERA: frames}, "stack it")
    info, stats, data = check_dataset(root, lengths, "stack it")
    everything = np.concatenate(states)
    np.testing.assert_allclose(np.array(data["observation.state"]), everything, rtol=1e-6)
    np.testing.assert_allclose(stats["observation.state"]["mean"], everything.mean(0), rtol=1e-5)
    np.testing.assert_allclose(stats["observation.state"]["std"], everything.std(0), rtol=1e-5)
    assert stats["observation.state"]["count"] == [sum(lengths)]
    assert info["features"]["observation.state"] == {"dtype": "float32", "shape": [3], "names": NAMES}
    assert info["features"][CAMERA]["shape"] == [32, 48, 3]


def test_camera_stats_are_those_of_every_pixel(tmp_path):
    rng = np.random.default_rng(5)
    frames = rng.integers(0, 256, (7, 16, 24, 3), dtype=np.uint8)
    frames[..., 1] = frames[..., 1] // 9 + 40  # a narrow channel: quantiles between few levels
    frames[..., 2] = np.where(frames[..., 2] > 200, 255, 0)  # two levels
    state = rng.normal(size=(7, 3))
    with LeRobotWriter(tmp_path / "dataset", fps=10, vectors={"observation.state": NAMES, "action": NAMES},
                       cameras={CAMERA: (16, 24)}) as writer:
        writer.add_episode({"observation.state": state, "action": state}, {CAMERA: frames}, "stack it")
    stats = json.loads((tmp_path / "dataset" / "meta/stats.json").read_text())[CAMERA]
    expected = feature_stats(frames.reshape(-1, 3) / 255.0)
    for key in ("min", "max", "mean", "std", "q01", "q10", "q50", "q90", "q99"):
        np.testing.assert_allclose(np.ravel(stats[key]), expected[key], atol=1e-6, err_msg=key)
    assert stats["count"] == [7]


def test_writer_refuses_bad_episodes(tmp_path):
    writer = LeRobotWriter(tmp_path / "d", fps=10, vectors={"action": NAMES}, cameras={CAMERA: (8, 8)})
    frames = np.zeros((4, 8, 8, 3), np.uint8)
    with pytest.raises(LeRobotError, match="same number"):
        writer.add_episode({"action": np.zeros((5, 3))}, {CAMERA: frames}, "t")
    with pytest.raises(LeRobotError, match=r"action: expected \(T, 3\)"):
        writer.add_episode({"action": np.zeros((4, 2))}, {CAMERA: frames}, "t")
    with pytest.raises(LeRobotError, match="integer frame rate"):
        LeRobotWriter(tmp_path / "e", fps=12.5, vectors={"action": NAMES}, cameras={})


@pytest.mark.slow
def test_export_lerobot_from_a_reconstruction(tmp_path):
    from robot_support import require_robot

    require_robot("placo", "mujoco")
    from warpskill.contract.reconstruction import Reconstruction
    from warpskill.synthetic import make_demonstration

    recon_path = tmp_path / "reconstruction.npz"
    Reconstruction(**make_demonstration("pick_up", seed=0, noise="none").truth).save(recon_path)
    # The command line in its own process: MuJoCo's offscreen GL context must not meet the
    # one another test's replay video set up in this process.
    command = [sys.executable, "-c", "import sys; from warpskill.cli import main; sys.exit(main(sys.argv[1:]))",
               "export", "lerobot", str(tmp_path / "ds"), str(recon_path), "--episodes", "1",
               "--image-size", "32", "32", "--cameras", "front"]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0 and "gl" in result.stderr.lower():
        pytest.skip(f"no offscreen renderer: {result.stderr.strip().splitlines()[-1]}")
    assert result.returncode == 0, result.stdout + result.stderr
    info = json.loads((tmp_path / "ds/meta/info.json").read_text())
    lengths = [info["total_frames"]]
    _, stats, data = check_dataset(tmp_path / "ds", lengths, "pick up the object")
    state = np.array(data["observation.state"])
    assert state.shape == (lengths[0], 8) and np.ptp(state[:, :7], axis=0).max() > 0.1  # the arm moves
    assert (tmp_path / "ds/contact_sheet.png").is_file()
