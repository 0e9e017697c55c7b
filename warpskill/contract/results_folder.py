"""The results folder ``OUT/<name>/``: its file names, what "finished" means, its writes and its lock.

Every command, benchmark and cluster task that writes a results folder goes through
:class:`ResultsFolder`, so the folder's layout (``docs/formats.md``, "Results folder") is
stated once:

- A result is *finished* when its file loads and validates, not when it exists: a file
  that does not load is reported once (``OUT/x/reconstruction.npz is corrupt (...):
  redoing it``) and the step is redone; so is a reconstruction made with other options
  than those asked for now (:meth:`ResultsFolder.finished_reconstruction`).
- Writes are atomic (a temporary file in the same folder, flushed to the disk, renamed over
  the result); a full disk leaves the previous file intact and says so in one line
  (:class:`ResultsFolderError`).
- One process at a time writes a folder: :meth:`ResultsFolder.locked` holds an exclusive
  ``flock`` on ``OUT/<name>/.lock``; a second command *waits* for the first to finish,
  after a line saying for which pid (it then finds the first one's results finished and
  skips them). The lock is released when its holder exits, however it exits; the lock file is removed
  when the holder finishes normally.
"""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import os
import time
from pathlib import Path
from typing import Callable, Iterator, TypeVar

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.npz import write_atomic
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.replay import Replay
from warpskill.file_lock import hold_lock

logger = logging.getLogger(__name__)

__all__ = ["ResultsFolder", "ResultsFolderError"]

Loaded = TypeVar("Loaded")

class _File:
    """A file of the results folder: ``folder.<name>`` is its path in that folder."""

    def __init__(self, name: str):
        self.name = name

    def __get__(self, folder, owner=None) -> Path:
        return self if folder is None else folder.path / self.name


class ResultsFolderError(OSError):
    """A result could not be written (the disk is full); the message says what was kept."""


class ResultsFolder:
    """The results folder of one demonstration, ``OUT/<name>/``.

    Args:
        path: the folder; created by the first write or lock.
    """

    RECONSTRUCTION = "reconstruction.npz"  #: the reconstruction (``warpskill optimize``)
    INITIALISATION = "initialisation.npz"  #: the physics-free initialisation alone (``warpskill bench synthetic``)
    DEMONSTRATION = "demonstration.npz"  #: the demonstration it was made from (``warpskill demo`` / ``run``)
    PLAN = "plan.npz"  #: the robot plan (``warpskill retarget``), with ``plan.csv`` beside it
    REPLAY = "replay.npz"  #: the simulated plan (``warpskill replay``)
    CHECKPOINT = "checkpoint.pt"  #: the optimiser's checkpoint while it runs
    ERROR = "error.txt"  #: why the last attempt failed (its traceback)
    ATTEMPTS = "attempts.log"  #: one line per attempt of a cluster run: "pid unix-time"
    TIMING = "timing.json"  #: the seconds each step of ``warpskill run`` took
    LOCK = ".lock"  #: the lock file; holds the pid of the process writing the folder

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)

    def __repr__(self) -> str:
        return f"ResultsFolder({str(self.path)!r})"

    reconstruction = _File(RECONSTRUCTION)
    initialisation = _File(INITIALISATION)
    demonstration = _File(DEMONSTRATION)
    plan = _File(PLAN)
    replay = _File(REPLAY)
    checkpoint = _File(CHECKPOINT)
    error = _File(ERROR)
    attempts = _File(ATTEMPTS)
    timing = _File(TIMING)

    @property
    def plan_csv(self) -> Path:
        return self.plan.with_suffix(".csv")

    def engine_replay(self, engine: str) -> Path:
        """The replay in one engine, ``replay_<engine>.npz``, when several engines replay one plan."""
        return self.path / f"replay_{engine}.npz"

    def load_finished(self, path: Path, load: Callable[[Path], Loaded]) -> Loaded | None:
        """``load(path)`` when the file loads; None when it is missing or corrupt (then it is redone).

        A corrupt file (``load`` raises ``ValueError`` or ``OSError``) is reported in one line.
        """
        if not path.is_file():
            return None
        try:
            return load(path)
        except (ValueError, OSError) as error:
            reason = str(error).removeprefix(f"{path}: ")
            logger.warning("%s is corrupt (%s): redoing it", path, reason)
            return None

    def finished_reconstruction(self, options: str | None = None) -> Reconstruction | None:
        """The reconstruction, if finished (:meth:`load_finished`) and made with ``options``.

        Args:
            options: the JSON of the options asked for now (``OptimizeOptions.to_json``);
                None: any options. A reconstruction that records other ones (the device
                aside: it changes only the rounding) is reported in one line and redone; one
                that records none is taken as it is.
        """
        recon = self.load_finished(self.reconstruction, Reconstruction.load)
        if recon is None or options is None or _same_options(str(recon.options), options):
            return recon
        logger.warning("%s: made with other options; redoing the step", self.reconstruction)
        return None

    def finished_demonstration(self) -> Demonstration | None:
        """The demonstration, if finished (:meth:`load_finished`)."""
        return self.load_finished(self.demonstration, Demonstration.load)

    def finished_replay(self) -> Replay | None:
        """The replay, if finished (:meth:`load_finished`)."""
        return self.load_finished(self.replay, Replay.load)

    def save(self, record, path: Path) -> Path:
        """``record.save(path)`` (an atomic write), creating the folder; returns ``path``.

        Raises:
            ResultsFolderError: the disk is full; the previous file at ``path`` is intact.
        """
        self.path.mkdir(parents=True, exist_ok=True)
        with _disk_full_said(path):
            record.save(path)
        return path

    def write_text(self, path: Path, text: str) -> Path:
        """Write ``text`` to ``path`` atomically, creating the folder; returns ``path``.

        Raises:
            ResultsFolderError: the disk is full; the previous file at ``path`` is intact.
        """
        self.path.mkdir(parents=True, exist_ok=True)
        with _disk_full_said(path):
            write_atomic(path, lambda file: file.write(text.encode()))
        return path

    def record_error(self, text: str) -> Path:
        """Write why the attempt failed (``text``, its traceback) to the error file; returns its path."""
        return self.write_text(self.error, text)

    def clear_error(self) -> None:
        """Remove the error file of an earlier attempt (this one succeeded)."""
        self.error.unlink(missing_ok=True)

    def log_attempt(self) -> int:
        """Append this attempt (``"pid unix-time"``) to the attempts log; returns the attempts logged."""
        self.path.mkdir(parents=True, exist_ok=True)
        with open(self.attempts, "a") as log:
            log.write(f"{os.getpid()} {time.time():.3f}\n")
        return len(self.attempts.read_text().splitlines())

    def clear_attempts(self) -> None:
        """Forget the attempts logged (a new run counts its own)."""
        self.attempts.unlink(missing_ok=True)

    @contextlib.contextmanager
    def locked(self) -> Iterator[ResultsFolder]:
        """Hold the folder's lock for the block; wait, after saying so, while another process holds it.

        Reentrant within a process: a nested block on the same folder shares the lock.
        """
        self.path.mkdir(parents=True, exist_ok=True)
        with hold_lock((self.path / self.LOCK).resolve(), self.path):
            yield self


def _same_options(made: str, asked: str) -> bool:
    """Whether the options JSON ``made`` (a reconstruction's) and ``asked`` agree on every
    field both record, the device aside. A reconstruction that records none (made
    elsewhere, or before options were recorded) is taken as it is."""
    if not made.strip():
        return True
    try:
        made_fields = json.loads(made)
    except ValueError:
        return False
    asked_fields = json.loads(asked)
    if not isinstance(made_fields, dict):
        return False
    made_fields.pop("device", None)
    asked_fields.pop("device", None)
    return _agree(made_fields, asked_fields)


def _agree(made: dict, asked: dict) -> bool:
    """Whether two nested option dicts agree on the keys both have (a field added since the
    reconstruction was made does not make it stale)."""
    for key in made.keys() & asked.keys():
        a, b = made[key], asked[key]
        if isinstance(a, dict) and isinstance(b, dict):
            if not _agree(a, b):
                return False
        elif a != b:
            return False
    return True


@contextlib.contextmanager
def _disk_full_said(path: Path) -> Iterator[None]:
    """Turn a full disk during the write of ``path`` into one line saying what was kept."""
    existed = path.exists()
    try:
        yield
    except OSError as error:
        if error.errno != errno.ENOSPC:
            raise
        kept = "the previous file is intact" if existed else "nothing was written"
        raise ResultsFolderError(f"no space left on device writing {path}; {kept}") from None
