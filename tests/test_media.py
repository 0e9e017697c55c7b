"""The media leaf (warpskill.media): MP4s are H.264 that PyAV decodes back, GIFs loop."""

from __future__ import annotations

import av
import imageio.v3 as iio
import numpy as np
import pytest

from warpskill.media import write_gif, write_mp4, write_video


def _frames(count: int, height: int, width: int) -> np.ndarray:
    """A bright square moving over a dark ramp: frames distinct from each other."""
    frames = np.zeros((count, height, width, 3), np.uint8)
    frames[..., 2] = np.linspace(0, 120, width, dtype=np.uint8)
    for k in range(count):
        frames[k, 4:12, 2 * k: 2 * k + 8] = (250, 250, 40)
    return frames


def _decode(path) -> tuple[str, float, np.ndarray]:
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        frames = np.stack([frame.to_ndarray(format="rgb24") for frame in container.decode(stream)])
        return stream.codec_context.name, float(stream.average_rate), frames


def test_mp4_is_h264_with_every_frame(tmp_path):
    frames = _frames(9, 32, 48)
    path = write_video(tmp_path / "clip.mp4", frames, 15.0)
    codec, fps, decoded = _decode(path)
    assert codec == "h264"
    assert fps == pytest.approx(15.0)
    assert decoded.shape == frames.shape
    assert np.abs(decoded.astype(int) - frames).mean() < 6.0  # lossy, but the same pictures
    data = path.read_bytes()
    assert data.find(b"moov") < data.find(b"mdat")  # faststart: the index first


def test_mp4_pads_odd_sizes_to_even(tmp_path):
    frames = _frames(3, 21, 31)
    _, _, decoded = _decode(write_mp4(tmp_path / "odd.mp4", frames, 10.0))
    assert decoded.shape == (3, 22, 32, 3)
    assert np.abs(decoded[:, :21, :31].astype(int) - frames).mean() < 6.0


def test_gif_keeps_frames_and_loops(tmp_path):
    frames = _frames(4, 16, 24)
    path = write_gif(tmp_path / "clip.gif", frames, 8.0)
    assert iio.imread(path).shape == frames.shape
    assert iio.immeta(path).get("loop") == 0


@pytest.mark.parametrize(("name", "frames", "problem"), [
    ("clip.avi", _frames(2, 8, 8), ".mp4 or .gif"),
    ("clip.mp4", _frames(2, 8, 8).astype(float), "uint8"),
    ("clip.mp4", np.zeros((0, 8, 8, 3), np.uint8), "T >= 1"),
])
def test_bad_input_is_named(tmp_path, name, frames, problem):
    with pytest.raises(ValueError, match=problem):
        write_video(tmp_path / name, frames, 10.0)
