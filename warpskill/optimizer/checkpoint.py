"""Checkpoints of a long optimisation: the best parameters per stage, written atomically, keyed by a fingerprint of the inputs."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Sequence

import numpy as np
import torch

from warpskill.contract.demonstration import Demonstration
from warpskill.optimizer.batching import Backend
from warpskill.optimizer.config import OptimizeConfig


class Checkpoint:
    """Per-stage optimiser state in one file, written atomically; ignored when ``path`` is None."""

    def __init__(self, path: str | os.PathLike | None, fingerprint: str):
        self.path = Path(path) if path is not None else None
        self.fingerprint = fingerprint
        self.stages: dict = {}
        if self.path is not None and self.path.exists():
            try:
                saved = torch.load(self.path, map_location="cpu", weights_only=True)
            except Exception as error:
                raise ValueError(
                    f"checkpoint {self.path} is not readable ({type(error).__name__}); move it away to start afresh"
                ) from None
            if not (isinstance(saved, dict) and {"fingerprint", "stages"} <= saved.keys()):
                raise ValueError(f"checkpoint {self.path} is not a warpskill checkpoint; move it away to start afresh")
            if saved["fingerprint"] == fingerprint:
                self.stages = saved["stages"]

    def load(self, stage: str) -> dict | None:
        return self.stages.get(stage)

    def save(self, stage: str, state: dict) -> None:
        if self.path is None:
            return
        self.stages[stage] = state
        self.path.parent.mkdir(parents=True, exist_ok=True)
        partial = self.path.with_name(self.path.name + ".partial")
        torch.save({"fingerprint": self.fingerprint, "stages": self.stages}, partial)
        os.replace(partial, self.path)


CHECKPOINT_FORMAT = 2  # bumped when the saved state's layout changes


def fingerprint(demos: Sequence[Demonstration], config: OptimizeConfig, seed: int, backend: Backend) -> str:
    """Identity of a run: a checkpoint resumes only the same demonstrations and settings."""
    digest = hashlib.sha256()
    for demo in demos:
        for array in (demo.hand_mask, demo.object_mask, demo.static_mask, demo.contact, demo.intrinsics.K):
            digest.update(np.ascontiguousarray(array).tobytes())
        digest.update(repr(demo.fps).encode())
    digest.update(repr((config, seed, backend.name, CHECKPOINT_FORMAT)).encode())
    return digest.hexdigest()
