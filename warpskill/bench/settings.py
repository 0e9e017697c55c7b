"""Where the benchmarks find their data: a folder given as an option or an environment variable.

No benchmark guesses a path beside the repository: a folder it needs and was not given is
a :class:`SettingError` naming the option and the variable that give it.
"""

from __future__ import annotations

import os
from pathlib import Path

DEV_DATA_VARIABLE = "WARPSKILL_DEV_DATA"
"""The development videos' folder (``annotations.json``, ``phases.csv``, ``actions.csv``)."""

TOOLS_VARIABLE = "WARPSKILL_TOOLS"
"""The folder of the second-opinion tools (``synthdemo.py``, ``synth_sthelse.py``)."""


class SettingError(ValueError):
    """A data folder that is neither given nor set, or that does not exist."""


def data_folder(given: str | os.PathLike | None, variable: str, option: str, what: str) -> Path:
    """``given``, else the environment variable ``variable``, as a folder that exists.

    Args:
        given: the folder the caller was given, or None.
        variable: the environment variable read when ``given`` is None.
        option: the command-line option that gives it (named in the error).
        what: what the folder holds, in words (named in the error).

    Raises:
        SettingError: neither is set, or the folder does not exist.
    """
    folder = given or os.environ.get(variable)
    if not folder:
        raise SettingError(f"no {what}: give {option} or set ${variable}")
    if not Path(folder).is_dir():
        raise SettingError(f"{folder}: no such folder ({what}; from {option if given else '$' + variable})")
    return Path(folder)
