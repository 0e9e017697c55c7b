"""Robot data for other tools: the robot's scene as MJCF, rollouts of skills over random layouts as a
labelled LeRobot dataset.

- :mod:`~warpskill.export.mjcf`: the robot's scene as one MJCF file for the user's own MuJoCo;

- :mod:`~warpskill.export.lerobot`: the LeRobot v3.0 dataset writer (pyarrow and PyAV only);
- :mod:`~warpskill.export.layouts`: the distribution of layouts over the Panda's reachable table;
- :mod:`~warpskill.export.rollouts`: plan, replay and film a skill in a layout (MuJoCo offscreen),
  the cameras' calibration;
- :mod:`~warpskill.export.dataset`: ``warpskill export lerobot``: the layouts each skill is given
  within its budget, labels and provenance, the dataset written whole or not at all.

Depends on the contract, the robot layer and :mod:`warpskill.media`; only the command line
and the benchmarks import it (``pyproject.toml``'s import contracts).
"""

from warpskill.lazy import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, globals(), {
    "dataset": ("export_lerobot", "ExportError", "ExportRequest"),
    "mjcf": ("write_mjcf",),
})
