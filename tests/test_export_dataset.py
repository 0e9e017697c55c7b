"""``warpskill export lerobot`` end to end: written whole or not at all, read back without warpskill's
writer (pyarrow, json, PyAV), labels, calibration and provenance present, the same seed the same bytes."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import signal
import subprocess
import sys

import av
import numpy as np
import pyarrow.parquet as pq
import pytest

from warpskill.cli import main
from warpskill.export.dataset import ExportError, ExportRequest, _Staging, export_lerobot

FRAME_SIZE = ("24", "16")  # W H [px]: tiny frames keep each export to a few seconds


@pytest.fixture(scope="module")
def recon_path(tmp_path_factory):
    """A pick up's ground-truth reconstruction in its results folder (``pick/reconstruction.npz``)."""
    from warpskill.contract.reconstruction import Reconstruction
    from warpskill.synthetic import make_demonstration

    path = tmp_path_factory.mktemp("sources") / "pick" / "reconstruction.npz"
    path.parent.mkdir()
    Reconstruction(**make_demonstration("pick_up", seed=0, noise="none").truth).save(path)
    return path


@pytest.fixture(scope="module")
def no_action_path(recon_path):
    """The same reconstruction without its action: a source that gives no skill."""
    arrays = dict(np.load(recon_path))
    arrays["action"] = np.array("")
    path = recon_path.parent.parent / "unknown.npz"
    np.savez(path, **arrays)
    return path


def export_command(out, *sources, episodes=2, extra=(), quiet=True):
    """The command line of an export in its own process (MuJoCo's offscreen GL stays out of pytest's)."""
    return [sys.executable, "-c", "import sys; from warpskill.cli import main; sys.exit(main(sys.argv[1:]))",
            "export", "lerobot", str(out), *map(str, sources), "--episodes", str(episodes),
            "--image-size", *FRAME_SIZE, *(["--quiet"] if quiet else []), *extra]


def run_export(out, *sources, **options):
    from robot_support import require_robot

    require_robot("placo", "mujoco")
    result = subprocess.run(export_command(out, *sources, **options), capture_output=True, text=True,
                            cwd=out.parent, env={**os.environ, "OMP_NUM_THREADS": "1"})
    if result.returncode not in (0, 2) and "gl" in result.stderr.lower():
        pytest.skip(f"no offscreen renderer: {result.stderr.strip().splitlines()[-1]}")
    return result


@pytest.fixture(scope="module")
def exported(tmp_path_factory, recon_path, no_action_path):
    """One export of a pick up (2 episodes) and a source without an action (left out)."""
    out = tmp_path_factory.mktemp("export") / "ds"
    result = run_export(out, recon_path, no_action_path)
    assert result.returncode == 0, result.stdout + result.stderr
    return out, result


def read_back(root):
    """info, provenance, the data and episode tables, and every camera's decoded frame times [s] and count."""
    info = json.loads((root / "meta/info.json").read_text())
    provenance = json.loads((root / "meta/warpskill.json").read_text())
    data = pq.read_table(root / info["data_path"].format(chunk_index=0, file_index=0)).to_pydict()
    episodes = pq.read_table(root / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    videos = {}
    for key, feature in info["features"].items():
        if feature["dtype"] == "video":
            with av.open(str(root / info["video_path"].format(video_key=key, chunk_index=0, file_index=0))) as file:
                videos[key] = [(float(frame.pts * frame.time_base), frame.width, frame.height)
                               for frame in file.decode(video=0)]
    return info, provenance, data, episodes, videos


@pytest.mark.slow
def test_dataset_reads_back_with_labels_and_metadata(exported, recon_path):
    out, result = exported
    info, provenance, data, episodes, videos = read_back(out)
    fps = info["fps"]
    assert len(episodes) == 2 and info["total_episodes"] == 2
    assert set(videos) == {"observation.images.front", "observation.images.top"}
    for e, episode in enumerate(episodes):
        rows = slice(episode["dataset_from_index"], episode["dataset_to_index"])
        length = episode["length"]
        assert data["episode_index"][rows] == [e] * length
        for key, frames in videos.items():  # every frame of the episode's span in its video, at k / fps
            start, stop = episode[f"videos/{key}/from_timestamp"], episode[f"videos/{key}/to_timestamp"]
            inside = [t for t, _, _ in frames if start - 0.5 / fps <= t < stop - 0.5 / fps]
            assert len(inside) == length
            assert np.max(np.abs(np.array(inside) - start - np.arange(length) / fps)) < 0.5 / fps
            assert np.max(np.abs(np.array(data["timestamp"][rows]) - np.arange(length) / fps)) < 0.5 / fps
        done, success, reward = (np.array(data[name][rows]) for name in ("next.done", "next.success", "next.reward"))
        assert done.tolist() == [False] * (length - 1) + [True]
        assert success.tolist() == done.tolist() and reward.tolist() == done.astype(float).tolist()
        assert episode["success"] is True and episode["engine"] == "mujoco" and episode["skill"] == "pick"
        assert set(json.loads(episode["layout"])) == {"object", "statics"} and episode["perturbation"] == "none"
    for key, frames in videos.items():
        assert len(frames) == len(data["index"]) and {(w, h) for _, w, h in frames} == {(24, 16)}
        camera = info["cameras"][key]
        assert (camera["width"], camera["height"]) == (24, 16) and camera["fx"] == camera["fy"] > 0
        pose = np.array(camera["base_from_camera"])
        np.testing.assert_allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-6)
    quaternions = np.array(data["observation.ee_pose"])[:, 3:]
    np.testing.assert_allclose(np.linalg.norm(quaternions, axis=1), 1.0, atol=1e-5)
    for key in ("observation.state", "action", "observation.ee_pose"):
        assert len(info["features"][key]["units"]) == info["features"][key]["shape"][0]
    assert info["features"]["observation.ee_pose"]["names"] == ["x", "y", "z", "qw", "qx", "qy", "qz"]
    pick, unknown = provenance["skills"]
    assert provenance["format"] == {"lerobot": "v3.0", "warpskill_export": 2}
    assert pick["reconstruction"]["sha256"] == hashlib.sha256(recon_path.read_bytes()).hexdigest()
    assert pick["episodes"] == [0, 1] and pick["action"] == "pick_up" and not pick["left_out"]
    assert unknown["episodes"] == [] and "action" in unknown["left_out"]
    assert "pick (pick_up): 2 episodes" in result.stdout and "unknown (unknown): left out" in result.stdout


@pytest.mark.slow
def test_same_seed_same_parquet_bytes(exported, recon_path, no_action_path, tmp_path):
    out, _ = exported
    again = tmp_path / "ds"
    again.mkdir()  # an empty folder is replaced by the finished dataset
    assert run_export(again, recon_path, no_action_path).returncode == 0
    for table in ("data/chunk-000/file-000.parquet", "meta/episodes/chunk-000/file-000.parquet"):
        assert (out / table).read_bytes() == (again / table).read_bytes(), table


@pytest.mark.slow
def test_killed_export_leaves_out_as_it_was(recon_path, tmp_path):
    from robot_support import require_robot

    require_robot("placo", "mujoco")
    out = tmp_path / "ds"
    out.mkdir()  # an empty folder to write into: it must stay (and stay empty)
    # The same skill five times: each skill is judged, then filmed and written, and its line printed;
    # the kill comes right after the first skill's line, while the second is judged.
    process = subprocess.Popen(export_command(out, *[recon_path] * 5, episodes=1, quiet=False), cwd=tmp_path,
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                               env={**os.environ, "OMP_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"})
    line = process.stdout.readline()
    while line and " episodes from " not in line:  # (other lines, e.g. a library's warning)
        line = process.stdout.readline()
    assert line and process.poll() is None, "the export ended before it could be killed"
    process.send_signal(signal.SIGKILL)
    process.wait()
    assert out.is_dir() and not any(out.iterdir())
    _Staging(out).discard()  # the next export beside it removes the killed one's folder
    assert not list(tmp_path.glob(".ds.partial-*"))


@pytest.mark.parametrize("arguments, message", [
    (["--cameras", "side"], "cameras"),
    (["--image-size", "31", "16"], "image size"),
    (["--episodes", "0"], "episodes"),
])
def test_bad_options_write_nothing(recon_path, tmp_path, capsys, arguments, message):
    out = tmp_path / "ds"
    assert main(["export", "lerobot", str(out), str(recon_path), *arguments]) == 2
    error = capsys.readouterr().err
    assert message in error and "nothing written" in error and len(error.strip().splitlines()) == 1
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_bad_sources_write_nothing(tmp_path, recon_path):
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"not an npz")
    full = tmp_path / "full"
    (full / "x").mkdir(parents=True)
    request = ExportRequest(episodes=1)
    with pytest.raises(ExportError, match="broken.npz: not a readable reconstruction"):
        export_lerobot(tmp_path / "ds", [recon_path, broken], request)
    with pytest.raises(ExportError, match="missing.npz: not a readable reconstruction"):
        export_lerobot(tmp_path / "ds", [tmp_path / "missing.npz"], request)
    with pytest.raises(ExportError, match="no reconstruction given"):
        export_lerobot(tmp_path / "ds", [], request)
    with pytest.raises(ExportError, match="must be absent or empty"):
        export_lerobot(full, [recon_path], request)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["broken.npz", "full"]


def test_failed_episode_is_labelled(tmp_path):
    """A kept failure (``--keep-failures``): no success nor reward on any frame, done on the last, its reason kept."""
    from warpskill.contract.skill import Layout
    from warpskill.export.dataset import _add_episode
    from warpskill.export.lerobot import LeRobotWriter
    from warpskill.export.rollouts import EE_POSE_NAMES, STATE_NAMES, Episode

    rng = np.random.default_rng(0)
    length = 5
    episode = Episode(Layout(object=(0.1, 0.5, 0.3), statics=((0.3, 0.6, 0.0),)), rng.normal(size=(length, 8)),
                      rng.normal(size=(length, 8)), rng.normal(size=(length, 7)),
                      {"front": rng.integers(0, 256, (length, 8, 8, 3), dtype=np.uint8)}, "put it behind the box",
                      success=False, reason="replay fails behind")
    with LeRobotWriter(tmp_path / "ds", fps=10, cameras={"observation.images.front": (8, 8)},
                       vectors={"observation.state": STATE_NAMES, "observation.ee_pose": EE_POSE_NAMES,
                                "action": STATE_NAMES},
                       scalars={"next.reward": "float32", "next.done": "bool", "next.success": "bool"}) as writer:
        assert _add_episode(writer, episode, "1044", attempt_index=3) == 0
    data = pq.read_table(tmp_path / "ds/data/chunk-000/file-000.parquet").to_pydict()
    row = pq.read_table(tmp_path / "ds/meta/episodes/chunk-000/file-000.parquet").to_pylist()[0]
    assert data["next.success"] == [False] * length and data["next.reward"] == [0.0] * length
    assert data["next.done"] == [False] * (length - 1) + [True]
    assert (row["success"], row["failure"], row["skill"], row["attempt"]) == (False, "replay fails behind", "1044", 3)
    assert json.loads(row["layout"]) == {"object": [0.1, 0.5, 0.3], "statics": [[0.3, 0.6, 0.0]]}


@pytest.mark.slow
def test_a_skill_takes_its_objects_noun_from_the_demonstration_beside_an_unnamed_reconstruction(tmp_path):
    """An older reconstruction without ``object_noun``: the skill exported names the demonstration's mug
    (held by its rim in every layout, not substituted), as the provenance does."""
    from warpskill.contract.reconstruction import Reconstruction
    from warpskill.export.dataset import load_sources
    from warpskill.synthetic import make_demonstration

    demo = dataclasses.replace(make_demonstration("pick_up", seed=0, noise="none"), object_noun="mug")
    (tmp_path / "mug").mkdir()
    demo.save(tmp_path / "mug/demonstration.npz")
    Reconstruction(**demo.truth).save(tmp_path / "mug/reconstruction.npz")
    [source] = load_sources([tmp_path / "mug/reconstruction.npz"])
    assert str(source.recon.object_noun) == "" and source.object_noun == "mug"
    assert source.skill().object_noun == "mug"
