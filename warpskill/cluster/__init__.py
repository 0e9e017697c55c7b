"""Many demonstrations on many cores and machines: Ray as the engine of ``optimize_many``.

Owns :func:`optimize_folder` (demonstrations spread over Ray tasks, each writing its
result and checkpoint into its own ``OUT/<name>/``; finished ones skipped on a rerun; a
killed worker retried from its checkpoint; a bad demonstration failing alone), its
:class:`Summary` and :class:`Outcome`, the Ray session it runs in (:func:`ray_session`: a
quiet local Ray with one worker per core, or an existing cluster) and
:func:`ray_available`. Ray is an optional extra (``pip install -e ".[cluster]"``),
imported only when a session starts. May import :mod:`warpskill.optimizer`,
:mod:`warpskill.contract` and :mod:`warpskill.engine`; never data, robot, visual or bench;
nothing imports it but the command line and the benchmarks.
"""

from warpskill.cluster.runner import (
    INSTALL_HINT,
    Outcome,
    Summary,
    optimize_folder,
    ray_available,
    ray_session,
)

__all__ = ["INSTALL_HINT", "Outcome", "Summary", "optimize_folder", "ray_available", "ray_session"]
