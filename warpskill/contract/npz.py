"""Reading and atomically writing the ``.npz`` files of the data contract."""

from __future__ import annotations

import contextlib
import os
import secrets
import zipfile
import zlib
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import BinaryIO

import numpy as np

# NotImplementedError: an unknown compression method; RuntimeError: an encrypted member.
_READ_ERRORS = (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, NotImplementedError, RuntimeError)


def read_npz(path: str | os.PathLike | BinaryIO, error: type[Exception]) -> dict[str, np.ndarray]:
    """Read every array of the ``.npz`` archive at ``path`` into memory.

    Arrays are read eagerly, so a corrupt member is reported here rather than on first use.
    Pickled (object) arrays, and members that are not ``.npy`` arrays, are refused.

    Args:
        path: the archive, or a binary file object holding it.
        error: exception class raised, with the path in its message, for a file that is
            not a readable ``.npz`` archive.

    Raises:
        FileNotFoundError: ``path`` does not exist.
    """
    try:  # opened (and closed) here: np.load leaks the handle it opens on a corrupt archive
        handle = contextlib.nullcontext(path) if hasattr(path, "read") else open(path, "rb")
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise error(f"{path}: not a readable .npz archive ({type(exc).__name__}: {exc})") from exc
    with handle as source:
        try:
            archive = np.load(source, allow_pickle=False)
        except _READ_ERRORS as exc:
            raise error(f"{path}: not a readable .npz archive ({type(exc).__name__}: {exc})") from exc
        if not isinstance(archive, np.lib.npyio.NpzFile):
            raise error(f"{path}: not an .npz archive (a single array)")
        arrays = {}
        with archive:
            for key in archive.files:
                try:
                    arrays[key] = archive[key]
                except _READ_ERRORS as exc:
                    raise error(f"{path}: {key}: unreadable ({type(exc).__name__}: {exc})") from exc
                if not isinstance(arrays[key], np.ndarray):  # a member without the .npy suffix: its raw bytes
                    raise error(f"{path}: {key}: not a NumPy array (an archive member without the .npy suffix)")
    return arrays


def save_npz_atomic(path: str | os.PathLike, arrays: Mapping[str, np.ndarray]) -> None:
    """Write ``arrays`` with ``numpy.savez_compressed`` to exactly ``path``, atomically (:func:`write_atomic`)."""
    write_atomic(path, lambda file: np.savez_compressed(file, **arrays))


def write_atomic(path: str | os.PathLike, write: Callable[[BinaryIO], object]) -> None:
    """Write a file with ``write(file)`` to exactly ``path``, atomically.

    The content is written to a new file in the same folder, flushed to the disk and
    renamed over ``path`` only once complete, so an existing file is never left
    half-written. The temporary file is removed if writing fails.
    """
    path = Path(path)
    temporary = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
    try:
        with open(temporary, "xb") as file:
            write(file)
            file.flush()
            os.fsync(file.fileno())
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
