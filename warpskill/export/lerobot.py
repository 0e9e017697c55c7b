"""A LeRobot dataset (format ``v3.0`` of the ``lerobot`` library), written with pyarrow and PyAV.

:class:`LeRobotWriter` takes whole episodes (state, action, camera frames, task text) and
writes the layout ``lerobot.datasets.LeRobotDataset`` reads (``docs/formats.md``, section
*LeRobot dataset*), without depending on ``lerobot``:

- ``data/chunk-000/file-000.parquet``: one row per frame, every episode in one file (one
  row group per episode): the vector features as fixed-size float32 lists, the scalar
  features (float32 or bool, e.g. ``next.reward``, ``next.done``) as plain columns, ``timestamp``
  (float32 [s], ``frame_index / fps``), ``frame_index``, ``episode_index``, ``index`` (over
  the dataset), ``task_index`` (int64);
- ``videos/<camera key>/chunk-000/file-000.mp4``: per camera every episode back to back
  in one H.264 stream at ``fps``, frame k at time k / fps exactly;
- ``meta/episodes/chunk-000/file-000.parquet``: one row per episode: its length, tasks,
  data rows (``dataset_from_index`` .. ``dataset_to_index``), file indices, the time span
  of each video (``videos/<key>/from_timestamp`` .. ``to_timestamp`` [s]), its own stats
  (``stats/<feature>/<stat>``) and any columns the caller adds (labels, provenance);
- ``meta/tasks.parquet``: the task texts (the pandas index ``task``) and ``task_index``;
- ``meta/stats.json``: per feature ``min``, ``max``, ``mean``, ``std``, ``count`` and the
  quantiles ``q01`` .. ``q99``; camera features per channel (3, 1, 1), pixels in [0, 1];
- ``meta/info.json``: ``codebase_version``, ``fps``, ``features`` (dtype, shape, names;
  the videos' codec info; any further keys the caller gives per feature, e.g. units), totals,
  ``splits``, the path templates and file sizes, and any top-level keys the caller adds.

One chunk and one file per kind: a dataset over ``DATA_FILE_MB`` of table data is refused
rather than split (a few hundred thousand frames of robot state).
"""

from __future__ import annotations

import json
from fractions import Fraction
from pathlib import Path

import av
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from warpskill.media import MP4_CODEC, MP4_QUALITY

__all__ = ["CODEBASE_VERSION", "LeRobotError", "LeRobotWriter", "feature_stats"]

CODEBASE_VERSION = "v3.0"
"""The ``lerobot`` dataset format written (``lerobot.datasets.lerobot_dataset.CODEBASE_VERSION``)."""

CHUNKS_SIZE = 1000  # files per chunk folder (lerobot's default)
DATA_FILE_MB = 100  # [MB] largest data file (lerobot's default; one file is written)
VIDEO_FILE_MB = 200  # [MB] lerobot's default largest video file (recorded in info.json)
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
EPISODES_PATH = "meta/episodes/chunk-000/file-000.parquet"
SCALAR_DTYPES = {"float32": (pa.float32(), np.float32), "bool": (pa.bool_(), np.bool_)}  # per-frame scalars
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)  # lerobot's default quantiles, stats keys q01 .. q99
INDEX_FEATURES = ("timestamp", "frame_index", "episode_index", "index", "task_index")


class LeRobotError(ValueError):
    """An episode that does not fit the dataset (shapes, lengths, camera names), or a dataset too large."""


def feature_stats(values: np.ndarray) -> dict[str, np.ndarray]:
    """``min``, ``max``, ``mean``, ``std``, ``count`` and quantiles of (T, D) ``values`` over frames."""
    values = np.asarray(values, dtype=np.float64)
    stats = {"min": values.min(0), "max": values.max(0), "mean": values.mean(0), "std": values.std(0),
             "count": np.array([len(values)])}
    for q in QUANTILES:
        stats[f"q{round(q * 100):02d}"] = np.quantile(values, q, axis=0)
    return stats


def _image_stats(frames: np.ndarray) -> dict[str, np.ndarray]:
    """Per-channel stats of (T, H, W, 3) uint8 frames, pixels in [0, 1], each (3, 1, 1); count: frames.

    Those :func:`feature_stats` gives over every pixel (quantiles linearly interpolated as
    ``np.quantile``'s), read off each channel's 256-bin histogram instead of sorting the pixels.
    """
    levels = np.arange(256, dtype=np.float64)
    stats: dict[str, list[float]] = {}
    for channel in range(3):
        counts = np.bincount(frames[..., channel].ravel(), minlength=256).astype(np.float64)
        total = counts.sum()
        mean = float(levels @ counts) / total
        seen = np.flatnonzero(counts)
        below = np.cumsum(counts)  # pixels at or below each level
        at_rank = lambda rank: float(np.searchsorted(below, rank, side="right"))  # noqa: E731
        values = {"min": float(seen[0]), "max": float(seen[-1]), "mean": mean,
                  "std": float(np.sqrt(max(float(levels**2 @ counts) / total - mean**2, 0.0)))}
        for q in QUANTILES:
            position = q * (total - 1)
            low, high = at_rank(np.floor(position)), at_rank(np.ceil(position))
            values[f"q{round(q * 100):02d}"] = low + (position - np.floor(position)) * (high - low)
        for key, value in values.items():
            stats.setdefault(key, []).append(value / 255.0)
    result = {key: np.array(value).reshape(3, 1, 1) for key, value in stats.items()}
    result["count"] = np.array([len(frames)])
    return result


def _merge_stats(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Dataset stats from per-episode stats: exact min, max, mean, std and count; quantiles
    as the count-weighted mean of the episodes' (lerobot aggregates them so too)."""
    counts = np.array([float(part["count"][0]) for part in parts])
    weights = (counts / counts.sum()).reshape(-1, *([1] * np.ndim(parts[0]["mean"])))
    means = np.stack([part["mean"] for part in parts])
    mean = (weights * means).sum(0)
    second = (weights * (np.stack([part["std"] for part in parts]) ** 2 + means**2)).sum(0)
    merged = {"min": np.min([part["min"] for part in parts], 0), "max": np.max([part["max"] for part in parts], 0),
              "mean": mean, "std": np.sqrt(np.maximum(second - mean**2, 0.0)), "count": np.array([int(counts.sum())])}
    for key in parts[0]:
        if key.startswith("q"):
            merged[key] = (weights * np.stack([part[key] for part in parts])).sum(0)
    return merged


class _VideoStream:
    """One camera's MP4: H.264 (``warpskill.media``'s codec and quality), yuv420p, frame k at k / fps."""

    def __init__(self, path: Path, fps: int, size: tuple[int, int]):
        path.parent.mkdir(parents=True, exist_ok=True)
        self.container = av.open(str(path), mode="w", options={"movflags": "faststart"})
        self.stream = self.container.add_stream(MP4_CODEC, rate=Fraction(fps))
        self.stream.height, self.stream.width = size
        self.stream.pix_fmt = "yuv420p"
        self.stream.codec_context.time_base = Fraction(1, fps)
        self.stream.options = {"crf": MP4_QUALITY}
        self.frames = 0

    def write(self, frames: np.ndarray) -> None:
        for image in frames:
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="rgb24")
            frame.pts = self.frames
            self.container.mux(self.stream.encode(frame))
            self.frames += 1

    def close(self) -> dict:
        """Flush and close; the ``info`` of the feature in ``info.json``."""
        self.container.mux(self.stream.encode())
        info = {"video.height": self.stream.height, "video.width": self.stream.width,
                "video.codec": self.stream.codec_context.codec.canonical_name, "video.pix_fmt": "yuv420p",
                "video.fps": int(self.stream.base_rate or self.stream.average_rate), "video.channels": 3,
                "video.is_depth_map": False, "has_audio": False}
        self.container.close()
        return info


class LeRobotWriter:
    """Writes a LeRobot v3.0 dataset into an empty folder, one whole episode at a time.

    Use as a context manager (or call :meth:`close`): the metadata is written on close.

    Args:
        root: the dataset folder (created; must be empty or absent).
        fps: frame rate [1/s], an integer as LeRobot requires.
        vectors: feature key -> names of its entries, e.g.
            ``{"observation.state": ["joint1", ...], "action": [...]}`` (float32 vectors).
        cameras: camera feature key (``observation.images.<name>``) -> (height, width) [px], even sizes.
        scalars: feature key -> dtype (``"float32"`` or ``"bool"``) of one value per frame.
        feature_info: feature key -> further keys of its entry in ``info.json`` (units, conventions).
        info: further top-level keys of ``info.json`` (camera calibrations).
        robot_type: ``info.json``'s ``robot_type``.
    """

    def __init__(self, root: Path, *, fps: int, vectors: dict[str, list[str]], cameras: dict[str, tuple[int, int]],
                 scalars: dict[str, str] | None = None, feature_info: dict[str, dict] | None = None,
                 info: dict | None = None, robot_type: str = "franka_panda"):
        root = Path(root)
        if root.exists() and any(root.iterdir()):
            raise LeRobotError(f"{root}: the dataset folder must be empty")
        if int(fps) != fps or fps <= 0:
            raise LeRobotError(f"fps: LeRobot needs a positive integer frame rate, got {fps}")
        scalars = dict(scalars or {})
        if not set(scalars.values()) <= set(SCALAR_DTYPES):
            raise LeRobotError(f"scalars: dtypes must be among {sorted(SCALAR_DTYPES)}, got {scalars}")
        for key, (height, width) in cameras.items():
            if height % 2 or width % 2:
                raise LeRobotError(f"{key}: H.264 in yuv420p needs even frame sizes, got {height} x {width}")
        self.root, self.fps, self.robot_type = root, int(fps), robot_type
        self.vectors = {key: list(names) for key, names in vectors.items()}
        self.cameras, self.scalars = dict(cameras), scalars
        self.feature_info, self.info = dict(feature_info or {}), dict(info or {})
        self.tasks: dict[str, int] = {}
        self.episodes: list[dict] = []
        self.stats: dict[str, list[dict]] = {key: [] for key in [*self.vectors, *self.scalars, *self.cameras,
                                                                  *INDEX_FEATURES]}
        self.frames = 0
        self.videos = {key: _VideoStream(root / VIDEO_PATH.format(video_key=key, chunk_index=0, file_index=0),
                                         self.fps, size) for key, size in self.cameras.items()}
        data_path = root / DATA_PATH.format(chunk_index=0, file_index=0)
        data_path.parent.mkdir(parents=True, exist_ok=True)
        self.data = pq.ParquetWriter(data_path, self._schema(), compression="snappy")

    def _schema(self) -> pa.Schema:
        fields = [pa.field(key, pa.list_(pa.float32(), len(names))) for key, names in self.vectors.items()]
        fields += [pa.field(key, SCALAR_DTYPES[dtype][0]) for key, dtype in self.scalars.items()]
        fields.append(pa.field("timestamp", pa.float32()))
        fields += [pa.field(name, pa.int64()) for name in INDEX_FEATURES[1:]]
        return pa.schema(fields)

    def add_episode(self, vectors: dict[str, np.ndarray], frames: dict[str, np.ndarray], task: str, *,
                    scalars: dict[str, np.ndarray] | None = None, columns: dict | None = None) -> int:
        """Append one episode; returns its index.

        Args:
            vectors: feature key -> (T, D) values, for every key given to the constructor.
            frames: camera key -> (T, H, W, 3) uint8 RGB, for every camera.
            task: what the episode does, in words.
            scalars: feature key -> (T,) values, for every scalar key given to the constructor.
            columns: further columns of the episode's row in ``meta/episodes`` (name -> a
                JSON-like value; the same names and kinds for every episode).

        Raises:
            LeRobotError: a missing or extra key, a wrong shape, lengths that differ.
        """
        scalars = dict(scalars or {})
        length = self._checked_length(vectors, frames, scalars)
        episode = len(self.episodes)
        task_index = self.tasks.setdefault(task, len(self.tasks))
        frame_index = np.arange(length, dtype=np.int64)
        values = {key: np.asarray(vectors[key], np.float32) for key in self.vectors}
        values.update({key: np.asarray(scalars[key], SCALAR_DTYPES[dtype][1]) for key, dtype in self.scalars.items()})
        values.update(timestamp=(frame_index / self.fps).astype(np.float32), frame_index=frame_index,
                       episode_index=np.full(length, episode, np.int64),
                       index=np.arange(self.frames, self.frames + length, dtype=np.int64),
                       task_index=np.full(length, task_index, np.int64))
        arrays = [pa.FixedSizeListArray.from_arrays(pa.array(values[key].reshape(-1)), len(names))
                  for key, names in self.vectors.items()]
        arrays += [pa.array(values[name]) for name in [*self.scalars, *INDEX_FEATURES]]
        self.data.write_table(pa.Table.from_arrays(arrays, schema=self.data.schema))
        row = {"episode_index": episode, "tasks": [task], "length": length,
               "data/chunk_index": 0, "data/file_index": 0,
               "dataset_from_index": self.frames, "dataset_to_index": self.frames + length}
        for key, video in self.videos.items():
            start = video.frames / self.fps
            video.write(frames[key])
            row.update({f"videos/{key}/chunk_index": 0, f"videos/{key}/file_index": 0,
                        f"videos/{key}/from_timestamp": start, f"videos/{key}/to_timestamp": video.frames / self.fps})
            self.stats[key].append(_image_stats(frames[key]))
        for key in [*self.vectors, *self.scalars, *INDEX_FEATURES]:
            self.stats[key].append(feature_stats(values[key].reshape(length, -1)))
        row.update({"meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0, **(columns or {})})
        for key, parts in self.stats.items():
            row.update({f"stats/{key}/{name}": value.tolist() for name, value in parts[-1].items()})
        self.episodes.append(row)
        self.frames += length
        return episode

    def _checked_length(self, vectors: dict, frames: dict, scalars: dict) -> int:
        if set(vectors) != set(self.vectors) or set(frames) != set(self.cameras) or set(scalars) != set(self.scalars):
            raise LeRobotError(f"episode: expected vectors {sorted(self.vectors)}, scalars {sorted(self.scalars)} and "
                               f"cameras {sorted(self.cameras)}, got {sorted(vectors)}, {sorted(scalars)} and "
                               f"{sorted(frames)}")
        lengths = {len(values) for values in scalars.values()}
        for key, values in scalars.items():
            if np.ndim(values) != 1:
                raise LeRobotError(f"{key}: expected (T,) values, got shape {np.shape(values)}")
        for key, names in self.vectors.items():
            shape = np.shape(vectors[key])
            if len(shape) != 2 or shape[1] != len(names):
                raise LeRobotError(f"{key}: expected (T, {len(names)}) values, got shape {shape}")
            lengths.add(shape[0])
        for key, (height, width) in self.cameras.items():
            images = frames[key]
            if images.dtype != np.uint8 or images.shape[1:] != (height, width, 3):
                raise LeRobotError(f"{key}: expected (T, {height}, {width}, 3) uint8 frames, got {images.shape} "
                                   f"{images.dtype}")
            lengths.add(len(images))
        if len(lengths) != 1 or 0 in lengths:
            raise LeRobotError(f"episode: every feature needs the same number (> 0) of frames, got {sorted(lengths)}")
        return lengths.pop()

    def close(self) -> Path:
        """Finish the videos and the data file; write the episodes, tasks, stats and info; return the root."""
        self.data.close()
        video_info = {key: video.close() for key, video in self.videos.items()}
        if not self.episodes:
            raise LeRobotError(f"{self.root}: no episode was added")
        data_mb = (self.root / DATA_PATH.format(chunk_index=0, file_index=0)).stat().st_size / 2**20
        if data_mb > DATA_FILE_MB:
            raise LeRobotError(f"{self.root}: {data_mb:.0f} MB of table data; one data file holds {DATA_FILE_MB} MB")
        meta = self.root / "meta"
        (meta / "episodes/chunk-000").mkdir(parents=True, exist_ok=True)
        pq.write_table(pa.Table.from_pylist(self.episodes), self.root / EPISODES_PATH)
        pq.write_table(_tasks_table(self.tasks), meta / "tasks.parquet")
        stats = {key: {name: value.tolist() for name, value in _merge_stats(parts).items()}
                 for key, parts in self.stats.items()}
        (meta / "stats.json").write_text(json.dumps(stats, indent=2))
        (meta / "info.json").write_text(json.dumps(self._info(video_info), indent=2))
        return self.root

    def _info(self, video_info: dict[str, dict]) -> dict:
        features = {key: {"dtype": "float32", "shape": [len(names)], "names": names}
                    for key, names in self.vectors.items()}
        features.update({key: {"dtype": dtype, "shape": [1], "names": None} for key, dtype in self.scalars.items()})
        for key, (height, width) in self.cameras.items():
            features[key] = {"dtype": "video", "shape": [height, width, 3], "names": ["height", "width", "channels"],
                             "info": video_info[key]}
        features["timestamp"] = {"dtype": "float32", "shape": [1], "names": None}
        features.update({name: {"dtype": "int64", "shape": [1], "names": None} for name in INDEX_FEATURES[1:]})
        for key, extra in self.feature_info.items():
            features[key].update(extra)
        return {"codebase_version": CODEBASE_VERSION, "robot_type": self.robot_type,
                "total_episodes": len(self.episodes), "total_frames": self.frames, "total_tasks": len(self.tasks),
                "chunks_size": CHUNKS_SIZE, "data_files_size_in_mb": DATA_FILE_MB,
                "video_files_size_in_mb": VIDEO_FILE_MB, "fps": self.fps,
                "splits": {"train": f"0:{len(self.episodes)}"}, "data_path": DATA_PATH,
                "video_path": VIDEO_PATH if self.cameras else None, "features": features, **self.info}

    def __enter__(self) -> "LeRobotWriter":
        return self

    def abort(self) -> None:
        """Release the files without writing the metadata; the folder is left as it is."""
        self.data.close()
        for video in self.videos.values():
            video.container.close()

    def __exit__(self, kind, error, trace) -> None:
        if kind is None:
            self.close()
        else:  # an episode failed
            self.abort()


def _tasks_table(tasks: dict[str, int]) -> pa.Table:
    """``meta/tasks.parquet``: ``task_index`` with the task texts as the pandas index ``task``
    (lerobot reads it with ``pandas.read_parquet`` and looks tasks up by that index)."""
    names = sorted(tasks, key=tasks.get)
    pandas_meta = {
        "index_columns": ["task"], "column_indexes": [], "pandas_version": "2.2.0", "creator": {"library": "pyarrow"},
        "columns": [{"name": "task_index", "field_name": "task_index", "pandas_type": "int64", "numpy_type": "int64",
                     "metadata": None},
                    {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object",
                     "metadata": None}],
    }
    table = pa.table({"task_index": pa.array([tasks[name] for name in names], pa.int64()),
                      "task": pa.array(names, pa.string())})
    return table.replace_schema_metadata({b"pandas": json.dumps(pandas_meta).encode()})
