"""Progress bars that draw only on a terminal.

A bar written into a log file is a stream of carriage-return lines; :func:`progress_bar` draws
one only when it is asked for and standard error is a terminal (or a Jupyter notebook, where
tqdm draws a widget). A leaf: imports tqdm only, no
other warpskill module.
"""

from __future__ import annotations

import sys

from tqdm.auto import tqdm
from tqdm.autonotebook import tqdm as _drawing_class
from tqdm.std import tqdm as _text_tqdm

__all__ = ["on_terminal", "progress_bar"]


def on_terminal() -> bool:
    """Whether a bar can be seen: standard error is an interactive terminal, or this is a notebook."""
    return _drawing_class is not _text_tqdm or bool(getattr(sys.stderr, "isatty", lambda: False)())


def progress_bar(iterable=None, *, enabled: bool = True, **options) -> tqdm:
    """A tqdm bar over ``iterable`` (or a manual one): drawn only if ``enabled`` and on a terminal.

    ``options`` are tqdm's (``total``, ``desc``, ``unit``, ...). A disabled bar still counts and
    passes ``iterable`` through, so callers treat both alike.
    """
    return tqdm(iterable, disable=not (enabled and on_terminal()), **options)
