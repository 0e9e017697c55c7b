"""The Rerun recording (warpskill.visual.rerun_view, ``warpskill view``): written, then read back
with Rerun's own RRD reader."""

from __future__ import annotations

import importlib.util
import sys

import imageio.v3 as iio
import numpy as np
import pytest

pytest.importorskip("rerun")
import rerun.chunk

from warpskill.cli import main
from warpskill.cli.common import installed
from warpskill.cli.view import view_folder
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.replay import Replay
from warpskill.contract.vocabulary import MODEL_HAND_LENGTH, MODEL_HAND_RADIUS
from warpskill.synthetic import make_demonstration
from warpskill.visual.rerun_scene import CLASS_IDS, rendered_labels
from warpskill.visual.rerun_view import view

HAS_ROBOT = all(importlib.util.find_spec(name) is not None for name in ("placo", "mujoco")) and installed(
    "example-robot-data"
)
needs_robot = pytest.mark.skipif(not HAS_ROBOT, reason="needs placo, mujoco and example-robot-data")


def small_demo(duration: float = 3.0):
    """A few frames of a noise-free synthetic pick-up, small images (fast)."""
    return make_demonstration("pick_up", seed=0, noise="none", image_size=(60, 80), fps=6.0, duration=duration)


@pytest.fixture(scope="module")
def demo():
    return small_demo()


@pytest.fixture(scope="module")
def recon(demo):
    return Reconstruction(**demo.truth)


@pytest.fixture(scope="module")
def robot_run(recon):
    if not HAS_ROBOT:
        pytest.skip("needs placo, mujoco and example-robot-data")
    from warpskill.robot.replaying import replay
    from warpskill.robot.retargeting import retarget

    plan = retarget(recon)
    return plan, replay(plan, recon)


def track(plan, recon, result=None):
    """The Panda's track the recording draws (:func:`warpskill.robot.robot_track`)."""
    from warpskill.robot import robot_track

    return robot_track(plan, float(recon.fps), result)


def read_rrd(path) -> dict[str, dict[str, list]]:
    """Entity path -> column name -> values (rows of every chunk; time columns as int64 ns).

    Temporal rows are sorted by the ``frame`` sequence; static chunks add their columns as is.
    """
    entities: dict[str, dict[str, list]] = {}
    for chunk in rerun.chunk.RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        columns = entities.setdefault(chunk.entity_path, {})
        for name in batch.schema.names:
            column = batch.column(name)
            if name == "time":
                column = column.cast("int64")
            columns.setdefault(name, []).extend(column.to_pylist())
    for columns in entities.values():
        if "frame" in columns:
            order = np.argsort(columns["frame"], kind="stable")
            n = len(order)
            for name, values in columns.items():
                if len(values) == n:
                    columns[name] = [values[i] for i in order]
    return entities


def one_per_row(values) -> np.ndarray:
    """Rows holding one instance each ([[x, y, z]], ...) as an array (rows, ...)."""
    assert all(len(v) == 1 for v in values), "expected one instance per row"
    return np.array([v[0] for v in values], dtype=float)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices of unit quaternions (..., 4) in (x, y, z, w) order."""
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def label_images(columns) -> np.ndarray:
    """(rows, H, W) uint8 from a SegmentationImage's buffer and format columns."""
    images = []
    for buffer, fmt in zip(columns["SegmentationImage:buffer"], columns["SegmentationImage:format"], strict=True):
        fmt = fmt[0]
        images.append(np.array(buffer[0], dtype=np.uint8).reshape(fmt["height"], fmt["width"]))
    return np.stack(images)


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


def test_scene_without_robot(tmp_path, demo, recon):
    out = view(recon, demo, path=tmp_path / "sub" / "scene.rrd")
    assert out == tmp_path / "sub" / "scene.rrd" and out.is_file()
    assert [p.name for p in out.parent.iterdir()] == ["scene.rrd"]  # no temporary file left
    data = read_rrd(out)
    expected = {
        "/world", "/world/ground", "/world/camera", "/world/camera/image", "/world/camera/image/masks",
        "/world/camera/image/rendered", "/world/hand", "/world/object", "/world/paths/hand_tip",
        "/world/paths/object", "/plots/signal/g", "/plots/state/grasped", "/plots/state/contact",
        "/world/truth/object",
    }
    assert expected <= set(data), expected - set(data)
    assert not any(name.startswith("/world/robot") for name in data)
    N, fps = recon.num_frames, float(recon.fps)

    # One sample per frame, on both timelines: frame k at k / fps seconds.
    for entity in ("/world/hand", "/world/object", "/world/camera/image/masks", "/world/camera/image/rendered",
                   "/plots/signal/g"):
        assert data[entity]["frame"] == list(range(N)), entity
        assert np.allclose(np.array(data[entity]["time"]) * 1e-9, np.arange(N) / fps, atol=1e-8), entity

    obj = data["/world/object"]
    assert np.allclose(one_per_row(obj["Boxes3D:centers"]), recon.object_pos, atol=1e-6)
    rot = quat_to_matrix(one_per_row(obj["Boxes3D:quaternions"]))
    assert np.allclose(rot, recon.object_rot, atol=1e-5)
    assert np.allclose(one_per_row(obj["Boxes3D:half_sizes"]), recon.object_size / 2, atol=1e-7)

    hand = data["/world/hand"]
    axis = quat_to_matrix(one_per_row(hand["Cylinders3D:quaternions"]))[:, :, 2]
    assert np.allclose(axis, recon.hand_rot[:, :, 2], atol=1e-5)
    tip = one_per_row(hand["Cylinders3D:centers"]) - axis * MODEL_HAND_LENGTH / 2
    assert np.allclose(tip, recon.hand_pos, atol=1e-5)
    assert np.allclose(one_per_row(hand["Cylinders3D:lengths"]), MODEL_HAND_LENGTH)
    assert np.allclose(one_per_row(hand["Cylinders3D:radii"]), MODEL_HAND_RADIUS)
    colors = np.array([c[0] for c in hand["Cylinders3D:colors"]])
    held, free = recon.grasped > 0.5, recon.grasped < 0.5
    assert held.any() and free.any()
    assert len({int(c) for c in colors[held]} & {int(c) for c in colors[free]}) == 0  # colour follows grasped

    assert np.allclose(one_per_row(data["/plots/signal/g"]["Scalars:scalars"]), recon.grasp)
    assert np.allclose(one_per_row(data["/plots/state/grasped"]["Scalars:scalars"]), recon.grasped)
    path = np.array(data["/world/paths/object"]["LineStrips3D:strips"][0][0])
    assert np.allclose(path, recon.object_pos, atol=1e-6)

    # Camera: at (0, 0, h), OpenCV axes, the contract's rotation; the pinhole has K and (W, H).
    camera = data["/world/camera"]
    assert np.allclose(camera["Transform3D:translation"][0][0], [0, 0, float(recon.camera_height)])
    R = np.array(camera["Transform3D:mat3x3"][0][0]).reshape(3, 3, order="F")  # column-major
    e = float(recon.camera_elevation)
    assert np.allclose(R[:, 1], [0, -np.sin(e), -np.cos(e)], atol=1e-6)
    assert np.allclose(R[:, 2], [0, np.cos(e), -np.sin(e)], atol=1e-6)
    pinhole = data["/world/camera/image"]
    K = np.array(pinhole["Pinhole:image_from_camera"][0][0]).reshape(3, 3, order="F")
    assert np.allclose(K, recon.camera_K, atol=1e-4)
    assert np.allclose(pinhole["Pinhole:resolution"][0][0], [recon.image_size[1], recon.image_size[0]])

    # Label images: the demonstration's masks exactly; the rendered truth agrees with them.
    masks = label_images(data["/world/camera/image/masks"])
    assert masks.shape == (N, *demo.image_size)
    assert np.array_equal(masks == CLASS_IDS["object"], demo.object_mask)
    rendered = label_images(data["/world/camera/image/rendered"])
    for name, mask in (("hand", demo.hand_mask & ~demo.object_mask), ("object", demo.object_mask)):
        assert iou(rendered == CLASS_IDS[name], mask) > 0.7, name


def test_rendered_labels_are_kept_for_the_same_values(recon):
    import dataclasses

    first = rendered_labels(recon)
    assert rendered_labels(dataclasses.replace(recon)) is first  # a copy with the same values
    assert not first.flags.writeable
    moved = dataclasses.replace(recon, object_pos=recon.object_pos + [0.05, 0.0, 0.0])
    second = rendered_labels(moved)
    assert second is not first and not np.array_equal(second, first)


def test_scene_shows_the_video_frames(tmp_path, demo, recon):
    frames = np.zeros((recon.num_frames, *demo.image_size, 3), np.uint8)
    frames[..., 0] = np.arange(recon.num_frames, dtype=np.uint8)[:, None, None] * 20  # red grows frame by frame
    frames[:, 10:30, 20:50, 1] = 200
    data = read_rrd(view(recon, demo, frames=frames, path=tmp_path / "scene.rrd"))
    video = data["/world/camera/image/video"]
    assert video["frame"] == list(range(recon.num_frames))
    decoded = np.stack([iio.imread(bytes(blob[0]), extension=".jpg") for blob in video["EncodedImage:blob"]])
    assert decoded.shape == frames.shape
    assert np.abs(decoded.astype(int) - frames).mean() < 4.0  # JPEG: the same pictures, nearly exact
    with pytest.raises(ValueError, match="frames"):
        view(recon, demo, frames=frames[:-1], path=tmp_path / "bad.rrd")


def test_scene_without_demo(tmp_path, recon):
    data = read_rrd(view(recon, path=tmp_path / "scene.rrd"))
    assert "/world/camera/image/rendered" in data and "/world/camera/image/masks" not in data
    assert "/plots/state/contact" not in data
    assert data["/world/object"]["frame"] == list(range(recon.num_frames))


@needs_robot
def test_scene_with_robot(tmp_path, demo, recon, robot_run):
    plan, result = robot_run
    data = read_rrd(view(recon, demo, track(plan, recon, result), result, path=tmp_path / "scene.rrd"))
    replayed = result.reconstruction
    F = replayed.num_frames
    links = [f"/world/robot/panda_link{i}" for i in range(8)] + [
        "/world/robot/panda_hand", "/world/robot/panda_leftfinger", "/world/robot/panda_rightfinger",
    ]
    for link in links:
        assert data[link]["frame"] == list(range(F)), link
        assert any(name.startswith(link + "/collision") for name in data), link  # geometry logged under it
    mesh = data["/world/robot/panda_link3/collision0"]
    vertices = np.array(mesh["Mesh3D:vertex_positions"][0], dtype=float)
    assert vertices.shape[1] == 3 and len(vertices) > 50
    assert len(mesh["Mesh3D:vertex_normals"][0]) == len(vertices)
    assert "Boxes3D:half_sizes" in data["/world/robot/panda_leftfinger/collision0"]
    # The replayed joints put the TCP where MuJoCo simulated it (the replay samples MuJoCo's body
    # poses one 2 ms physics step behind its joints: mm, not exact).
    tcp = data["/world/robot/panda_hand_tcp"]
    assert np.abs(one_per_row(tcp["Transform3D:translation"]) - replayed.hand_pos).max() < 1e-3
    tcp_rot = np.array([np.array(m[0]).reshape(3, 3, order="F") for m in tcp["Transform3D:mat3x3"]])
    hand_rot = tcp_rot @ np.diag([1.0, -1.0, -1.0])  # TCP frame -> hand frame of docs/formats.md
    assert np.abs(hand_rot - replayed.hand_rot).max() < 1e-2
    base = data["/world/robot/panda_link0"]
    assert np.allclose(one_per_row(base["Transform3D:translation"])[0], plan.base[:3, 3], atol=1e-6)
    rep = data["/world/replay/object"]
    assert rep["frame"] == list(range(F))
    assert np.allclose(one_per_row(rep["Boxes3D:centers"]), replayed.object_pos, atol=1e-6)
    gripper = one_per_row(data["/plots/signal/gripper"]["Scalars:scalars"])
    times = plan.start_time + np.arange(F) / float(recon.fps)
    assert np.allclose(gripper, np.interp(times, plan.t, plan.gripper))
    assert gripper.min() < 0.5 * gripper.max()  # it closes on the object
    # The reconstruction's own entities are unchanged by the robot.
    assert np.allclose(one_per_row(data["/world/object"]["Boxes3D:centers"]), recon.object_pos, atol=1e-6)


@needs_robot
def test_robot_without_replay_follows_the_plan(tmp_path, recon, robot_run):
    plan, result = robot_run
    data = read_rrd(view(recon, robot=track(plan, recon), path=tmp_path / "scene.rrd"))
    F = result.reconstruction.num_frames
    tcp = one_per_row(data["/world/robot/panda_hand_tcp"]["Transform3D:translation"])
    assert tcp.shape == (F, 3)
    times = plan.start_time + np.arange(F) / float(recon.fps)
    planned = np.stack([np.interp(times, plan.t, plan.tcp[:, i, 3]) for i in range(3)], axis=1)
    assert np.abs(tcp - planned).max() < 5e-4
    assert not any(name.startswith("/world/replay") for name in data)


def write_results_folder(folder, demo, recon, robot_run=None):
    """A folder as ``warpskill demo`` leaves it (without optimising: the truth is the reconstruction)."""
    demo.save(folder / "demonstration.npz")
    recon.save(folder / "reconstruction.npz")
    if robot_run is not None:
        plan, result = robot_run
        plan.save(folder / "plan.npz")
        result.save(folder / "replay.npz")
    return folder


@needs_robot
def test_view_folder(tmp_path, demo, recon, robot_run):
    _, result = robot_run
    write_results_folder(tmp_path, demo, recon, robot_run)
    out = view_folder(tmp_path)
    assert out == tmp_path / "scene.rrd"
    data = read_rrd(out)
    assert "/world/camera/image/masks" in data
    # replay.npz stores the simulated joints: the arm is the simulated one, as from the Replay itself.
    stored = Replay.load(tmp_path / "replay.npz")
    assert np.array_equal(stored.joints, result.joints)
    direct = read_rrd(view(recon, demo, track(robot_run[0], recon, result), result, path=tmp_path / "direct.rrd"))
    for link in ("/world/robot/panda_link4", "/world/robot/panda_hand_tcp"):
        assert data[link]["Transform3D:translation"] == direct[link]["Transform3D:translation"], link
    tcp = one_per_row(data["/world/robot/panda_hand_tcp"]["Transform3D:translation"])
    assert np.abs(tcp - result.reconstruction.hand_pos).max() < 1e-3
    assert np.allclose(one_per_row(data["/world/replay/object"]["Boxes3D:centers"]),
                       result.reconstruction.object_pos, atol=1e-6)
    other = view_folder(tmp_path, path=tmp_path / "elsewhere" / "x.rrd")
    assert other.is_file()


@needs_robot
def test_view_folder_skips_a_replay_without_joints(tmp_path, demo, recon, robot_run, capsys):
    write_results_folder(tmp_path, demo, recon, robot_run)
    arrays = dict(np.load(tmp_path / "replay.npz"))
    del arrays["joints"]  # as written before the joints were stored
    np.savez(tmp_path / "replay.npz", **arrays)
    data = read_rrd(view_folder(tmp_path))
    assert "replay skipped" in capsys.readouterr().out
    assert "/world/robot/panda_hand_tcp" in data and not any(name.startswith("/world/replay") for name in data)


@needs_robot
def test_cli_view(tmp_path, demo, recon, robot_run, capsys):
    folder = tmp_path / "out"
    folder.mkdir()
    write_results_folder(folder, demo, recon, robot_run)
    assert main(["view", str(folder)]) == 0
    out = capsys.readouterr().out
    assert out == f"scene: {folder / 'scene.rrd'} (open with: rerun {folder / 'scene.rrd'})\n"
    data = read_rrd(folder / "scene.rrd")
    assert {"/world/robot/panda_hand", "/world/replay/object", "/world/camera/image/masks"} <= set(data)
    assert main(["view", str(folder), "-o", str(tmp_path / "x" / "mine.rrd")]) == 0
    assert (tmp_path / "x" / "mine.rrd").is_file()


def test_cli_view_errors_are_one_line(tmp_path, recon, capsys, monkeypatch):
    assert main(["view", str(tmp_path / "missing")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("warpskill: error:") and err.count("\n") == 1 and "missing" in err
    recon.save(tmp_path / "reconstruction.npz")
    assert main(["view", str(tmp_path / "reconstruction.npz")]) == 1
    assert "not a folder" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "rerun", None)  # makes `import rerun` fail
    assert main(["view", str(tmp_path)]) == 1
    captured = capsys.readouterr()
    assert 'pip install -e ".[viewer]"' in captured.err and captured.err.count("\n") == 1
    assert "Traceback" not in captured.err and captured.out == ""
    assert not (tmp_path / "scene.rrd").exists()


def test_pipeline_writes_the_scene_beside_the_pictures(tmp_path, demo, recon, capsys, monkeypatch):
    """What ``warpskill demo`` and ``optimize`` do after the pictures (cli.common.save_scene)."""
    from warpskill.cli.common import save_scene

    save_scene(recon, demo, tmp_path)
    path = tmp_path / "scene.rrd"
    assert capsys.readouterr().out == f"scene: {path} (open with: rerun {path})\n"
    assert "/world/camera/image/masks" in read_rrd(path)
    monkeypatch.setitem(sys.modules, "rerun", None)
    save_scene(recon, demo, tmp_path / "none")
    assert capsys.readouterr().out == 'scene: none (the 3D recording needs rerun-sdk: pip install -e ".[viewer]")\n'
    assert not (tmp_path / "none" / "scene.rrd").exists()


def test_view_folder_reconstruction_only(tmp_path, recon):
    recon.save(tmp_path / "reconstruction.npz")
    data = read_rrd(view_folder(tmp_path))
    assert "/world/hand" in data and "/world/camera/image/masks" not in data
    assert not any(name.startswith(("/world/robot", "/world/replay")) for name in data)


def test_bad_inputs(tmp_path, demo, recon):
    with pytest.raises(TypeError, match="recon"):
        view(demo, path=tmp_path / "x.rrd")
    with pytest.raises(TypeError, match="demo"):
        view(recon, recon, path=tmp_path / "x.rrd")
    other = small_demo(duration=2.0)
    with pytest.raises(ValueError, match="frames"):
        view(recon, other, path=tmp_path / "x.rrd")
    with pytest.raises(TypeError, match="plan"):
        view(recon, plan="plan.npz", path=tmp_path / "x.rrd")
    with pytest.raises(TypeError, match="replay"):
        view(recon, replay=recon, path=tmp_path / "x.rrd")
    with pytest.raises(FileNotFoundError, match="reconstruction.npz"):
        view_folder(tmp_path)
    with pytest.raises(FileNotFoundError):
        view_folder(tmp_path / "missing")
    assert not (tmp_path / "x.rrd").exists()


def test_missing_rerun_says_what_to_install(tmp_path, recon, monkeypatch):
    monkeypatch.setitem(sys.modules, "rerun", None)  # makes `import rerun` fail
    with pytest.raises(ModuleNotFoundError, match=r'pip install -e "\.\[viewer\]"'):
        view(recon, path=tmp_path / "x.rrd")
