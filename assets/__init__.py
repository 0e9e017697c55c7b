"""Files warpskill reads at run time, installed as the package data ``warpskill.assets``.

- ``robot_scene.toml``: the robot scene both replays (MuJoCo, Newton) and the replay video
  read: table, object, contacts, the Panda's drives, solver options, camera and lights
  (loaded by :func:`warpskill.robot.scene_config.load_scene_config`).
- ``examples/``: a tiny Something-Else annotation set (one synthetic video) for
  ``warpskill bench something-else``; see ``examples/README.md``; and
  ``examples/own_recording/``: a short synthetic textured video and its one-frame polygons
  for ``warpskill run`` (the README's "Your own recording").

Nothing here is generated at run time.
"""

from __future__ import annotations

import importlib.resources
from pathlib import Path


def path(name: str) -> Path:
    """The installed asset file ``name`` (a path relative to this folder, e.g. ``"robot_scene.toml"``).

    Raises:
        FileNotFoundError: no such asset.
    """
    resource = importlib.resources.files(__name__).joinpath(*name.split("/"))
    found = Path(str(resource))
    if not found.is_file():
        raise FileNotFoundError(f"no asset {name!r} in {Path(str(importlib.resources.files(__name__)))}")
    return found
