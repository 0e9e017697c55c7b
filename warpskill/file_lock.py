"""A process-exclusive, reentrant lock on a file (``flock``): the lock of every results folder.

A second process that asks for a held lock says which pid holds it and waits. The lock is
released when its holder exits, however it exits; the file is removed as the holder's block
ends. A leaf: imports no other warpskill module.
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import os
from pathlib import Path
from typing import Iterator

logger = logging.getLogger(__name__)

__all__ = ["hold_lock"]

# The lock files this process holds, each with its open handle and how many blocks hold it:
# flock excludes a second open of the same file even within one process, so nested blocks share one.
_HELD: dict[Path, list] = {}


@contextlib.contextmanager
def hold_lock(lock: Path, folder: Path) -> Iterator[None]:
    """Hold the exclusive lock on the file ``lock`` (an absolute path; the holder's pid written in
    it) for the block, waiting while another process holds it (saying so, naming ``folder``).

    Reentrant within a process: a nested block on the same file shares the lock.
    """
    if lock in _HELD:
        _HELD[lock][1] += 1
        try:
            yield
        finally:
            _HELD[lock][1] -= 1
        return
    handle = _open_locked(lock, folder)
    with handle:
        handle.seek(0)
        handle.truncate()
        handle.write(f"{os.getpid()}\n")
        handle.flush()
        _HELD[lock] = [handle, 1]
        try:
            yield
        finally:
            del _HELD[lock]
            lock.unlink(missing_ok=True)  # while still held: a waiter then finds its file gone and retries


def _open_locked(lock: Path, folder: Path):
    """The lock file ``lock``, open and exclusively locked by this process.

    A holder removes the file as it finishes, so a process that waited on the old file
    retries on a new one until the file it locked is the one at ``lock``.
    """
    while True:
        handle = open(lock, "a+")
        _acquire(handle, folder)
        try:
            if os.stat(lock).st_ino == os.fstat(handle.fileno()).st_ino:
                return handle
        except FileNotFoundError:
            pass
        handle.close()


def _acquire(handle, folder: Path) -> None:
    """Take the exclusive lock on ``handle``; if another process has it, say which and wait."""
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return
    except BlockingIOError:
        pass
    handle.seek(0)
    pid = handle.read().strip()
    holder = f"pid {pid}" if pid.isdigit() else "another process"
    logger.info("%s: being written by %s; waiting for it to finish", folder, holder)
    fcntl.flock(handle, fcntl.LOCK_EX)
