"""Lazy re-exports for package ``__init__`` modules (PEP 562): names load on first use."""

from __future__ import annotations

import importlib
from typing import Callable, Mapping, Sequence


def lazy_exports(package: str, namespace: dict,
                 exports: Mapping[str | None, Sequence[str]]) -> tuple[list[str], Callable, Callable]:
    """A package's ``__all__`` and module ``__getattr__`` and ``__dir__``, importing ``exports`` on first access.

    Args:
        package: the package's ``__name__``.
        namespace: the package's ``globals()``; a loaded name is cached there.
        exports: submodule (relative to the package) -> the public names it defines; the key
            ``None`` lists names that are themselves submodules (``warpskill.data``).

    Returns:
        ``(__all__, __getattr__, __dir__)``, to assign in the package's ``__init__``.
    """
    home = {name: module for module, names in exports.items() for name in names}

    def __getattr__(name: str):
        if name not in home:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        if home[name] is None:
            value = importlib.import_module(f".{name}", package)
        else:
            value = getattr(importlib.import_module(f".{home[name]}", package), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(home))

    return sorted(home), __getattr__, __dir__
