"""Warp's messages ("Module ... load on device", the init banner): quiet unless asked for.

One switch for every Warp user in the process, the engine's kernels and Newton's alike (they
share Warp's config): :func:`configure_warp_log` is called when the engine is imported and by
the command line (``warpskill --verbose``) before any command runs. The choice travels in the
environment variable :data:`VERBOSE_ENV`, so worker processes (Ray) and a later import of the
engine keep it. A leaf: imports Warp only, no other warpskill module.
"""

from __future__ import annotations

import os

import warp as wp

__all__ = ["VERBOSE_ENV", "configure_warp_log"]

VERBOSE_ENV = "WARPSKILL_VERBOSE"
"""Environment variable: ``1`` shows Warp's messages; anything else, or unset, hides them."""


def configure_warp_log(verbose: bool | None = None) -> None:
    """Show (``verbose``) or hide Warp's info messages; None: as :data:`VERBOSE_ENV` says.

    Takes effect for modules loaded afterwards, so call it before Warp or Newton compiles anything.
    """
    if verbose is None:
        verbose = os.environ.get(VERBOSE_ENV) == "1"
    else:
        os.environ[VERBOSE_ENV] = "1" if verbose else "0"
    wp.config.quiet = not verbose  # Warp before log levels (up to 1.10)
    if hasattr(wp.config, "log_level"):  # Warp with log levels: info messages are the module loads
        wp.config.log_level = wp.LOG_INFO if verbose else wp.LOG_WARNING
