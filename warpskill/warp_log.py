"""Warp's messages (the missing-driver warning, the init banner, "Module ... load on device"):
quiet unless asked for.

One switch for every Warp user in the process, the engine's kernels and Newton's alike (they
share Warp's config): :func:`configure_warp_log` is called when the engine is imported and by
the command line (``warpskill --verbose``) before any command runs, and initialises Warp then.
The choice travels in the environment variable :data:`VERBOSE_ENV`, so worker processes (Ray)
and a later import of the engine keep it. A leaf: imports Warp only, no other warpskill module.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import sys

import warp as wp

__all__ = ["VERBOSE_ENV", "configure_warp_log", "cuda_driver_found"]

VERBOSE_ENV = "WARPSKILL_VERBOSE"
"""Environment variable: ``1`` shows Warp's messages; anything else, or unset, hides them."""

_CUDA_DRIVERS = ("nvcuda.dll",) if sys.platform == "win32" else ("libcuda.so", "libcuda.so.1")
"""The libraries Warp's native code loads as the CUDA driver, in its order."""


def configure_warp_log(verbose: bool | None = None) -> None:
    """Show (``verbose``) or hide Warp's messages, then initialise Warp; None: as :data:`VERBOSE_ENV` says.

    Module-load messages follow the switch from then on, so call it before Warp or Newton
    compiles anything. Verbose, it says once which device Warp runs on.
    """
    if verbose is None:
        verbose = os.environ.get(VERBOSE_ENV) == "1"
    else:
        os.environ[VERBOSE_ENV] = "1" if verbose else "0"
    wp.config.quiet = not verbose  # Warp before log levels (up to 1.10)
    if hasattr(wp.config, "log_level"):  # Warp with log levels: info messages are the module loads
        wp.config.log_level = wp.LOG_INFO if verbose else wp.LOG_WARNING
    _init_warp()
    if verbose:
        _announce_device()


def cuda_driver_found() -> bool:
    """Whether this machine can load a CUDA driver library (what Warp's native init looks for)."""
    for name in _CUDA_DRIVERS:
        with contextlib.suppress(OSError):
            ctypes.CDLL(name)
            return True
    return False


@functools.cache
def _init_warp() -> None:
    """``wp.init()``, its native missing-driver warning silenced where no CUDA driver can be loaded.

    Every CPU machine would print that line on every run; with a driver nothing is hidden.
    """
    if cuda_driver_found():
        wp.init()
        return
    with _native_stderr_silenced():
        wp.init()


@contextlib.contextmanager
def _native_stderr_silenced():
    """File descriptor 2 (where native code writes) to the null device while the block runs."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


@functools.cache
def _announce_device() -> None:
    """One line on standard error: Warp's version and the device it runs on by default."""
    device = wp.get_preferred_device()
    detail = device.name if device.is_cuda or cuda_driver_found() else "no CUDA driver"
    print(f"warpskill: Warp {wp.__version__} on {device.alias} ({detail})", file=sys.stderr)
