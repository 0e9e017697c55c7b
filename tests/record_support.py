"""Checks every record file shares (Demonstration, Reconstruction)."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import pytest


def assert_save_is_atomic(record, path: Path, spoil: Callable[[], None]) -> None:
    """A ``record.save(path)`` that fails (after ``spoil()`` made the record unwritable) leaves the
    file it replaces whole and no temporary file beside it."""
    record.save(path)
    before = path.read_bytes()
    spoil()
    with pytest.raises(Exception):
        record.save(path)
    assert path.read_bytes() == before
    assert [p.name for p in path.parent.iterdir()] == [path.name]
