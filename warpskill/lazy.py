"""Lazy re-exports for package ``__init__`` modules (PEP 562): names load on first use."""

from __future__ import annotations

import importlib
from typing import Callable


def lazy_exports(package: str, exports: dict[str, str], namespace: dict) -> tuple[Callable, Callable]:
    """Module ``__getattr__`` and ``__dir__`` that import ``exports`` on first access.

    Args:
        package: the package's ``__name__``.
        exports: public name -> submodule (relative to the package) that defines it, or
            ``None`` for a name that is itself a submodule (``warpskill.data``).
        namespace: the package's ``globals()``; a loaded name is cached there.
    """

    def __getattr__(name: str):
        if name not in exports:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        if exports[name] is None:
            value = importlib.import_module(f".{name}", package)
        else:
            value = getattr(importlib.import_module(f".{exports[name]}", package), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(exports))

    return __getattr__, __dir__
