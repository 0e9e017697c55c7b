"""The replay file: a robot plan's simulated scene in the reconstruction keys, and its verdict.

``replay.npz`` holds the keys of a reconstruction (``docs/formats.md``), so that every tool that
judges reconstructions can judge a replay: ``hand_*`` is the gripper's TCP, ``object_*`` the
simulated object, the sizes those simulated. Extra keys: ``success``, ``engine``,
``replay_time`` [s] and ``joints`` (F, 7) [rad].
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from warpskill.contract.evaluation import Evaluation, evaluate
from warpskill.contract.npz import read_npz, save_npz_atomic
from warpskill.contract.reconstruction import (
    FIELD_SHAPES,
    OPTIONAL_FIELDS,
    Reconstruction,
    ReconstructionError,
)

__all__ = ["Replay"]


@dataclasses.dataclass
class Replay:
    """The outcome of :func:`replay`.

    Attributes:
        reconstruction: the replayed motion (gripper and simulated object).
        evaluation: the paper's criteria applied to it.
        engine: ``mujoco`` or ``newton``.
        replay_time: wall-clock time [s] of the simulation.
        joints: (F, 7) simulated arm joint positions at the sampled frames.
    """

    reconstruction: Reconstruction
    evaluation: Evaluation
    engine: str
    replay_time: float
    joints: np.ndarray

    @property
    def success(self) -> bool:
        """Whether the replayed motion achieves the action."""
        return self.evaluation.success

    def save(self, path: str | os.PathLike) -> None:
        """Write ``replay.npz`` atomically: the reconstruction keys of ``docs/formats.md`` (the
        simulated scene) plus ``success``, ``engine``, ``replay_time`` and ``joints``."""
        arrays = {name: getattr(self.reconstruction, name) for name in FIELD_SHAPES}
        arrays.update(
            success=np.array(self.success),
            engine=np.array(self.engine),
            replay_time=np.array(self.replay_time),
            joints=np.asarray(self.joints, dtype=float),
        )
        save_npz_atomic(path, arrays)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Replay":
        """Read a ``replay.npz`` written by :meth:`save`; the evaluation is recomputed.

        Raises:
            ReconstructionError: naming the file and the key that is missing or malformed
                (``joints`` not (F, 7) finite numbers, ``engine`` not a string, ``replay_time``
                not a finite time >= 0, a bad reconstruction key), or an action the replay
                cannot be judged by (unknown, or ``put_*`` without a static object).
        """
        arrays = read_npz(path, ReconstructionError)
        missing = sorted({"engine", "joints"} - set(arrays))
        if missing:
            raise ReconstructionError(f"{path}: not a replay file, missing key(s) {', '.join(missing)}")
        missing = [name for name in (*FIELD_SHAPES, "replay_time") if name not in arrays and name not in OPTIONAL_FIELDS]
        if missing:
            raise ReconstructionError(f"{path}: missing key(s) {', '.join(missing)}")
        joints, engine, replay_time = arrays["joints"], arrays["engine"], arrays["replay_time"]
        if joints.dtype.kind not in "iuf" or joints.ndim != 2 or joints.shape[1] != 7:
            raise ReconstructionError(f"{path}: joints must be (F, 7) numbers, got {joints.dtype} of shape {joints.shape}")
        if not np.all(np.isfinite(joints)):
            raise ReconstructionError(f"{path}: joints: contains NaN or inf")
        if engine.dtype.kind != "U" or engine.ndim != 0:
            raise ReconstructionError(f"{path}: engine: expected a string, got {engine.dtype} of shape {engine.shape}")
        if replay_time.dtype.kind not in "iuf" or replay_time.ndim != 0 or not np.isfinite(replay_time) or replay_time < 0:
            raise ReconstructionError(f"{path}: replay_time: expected a finite scalar >= 0 [s], got {replay_time!r}")
        fields = {name: arrays.get(name, OPTIONAL_FIELDS.get(name)) for name in FIELD_SHAPES}
        try:
            recon = Reconstruction(**fields)
            evaluation = evaluate(recon, str(recon.action) or None)
        except ReconstructionError as error:
            raise ReconstructionError(f"{path}: {error}") from None
        except ValueError as error:  # no known action, or a put_* action without a static object
            raise ReconstructionError(f"{path}: action: cannot judge the replay: {error}") from None
        return cls(
            reconstruction=recon,
            evaluation=evaluation,
            engine=str(engine),
            replay_time=float(replay_time),
            joints=joints.astype(float),
        )
