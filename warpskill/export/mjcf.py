"""The robot's scene as one MJCF file for the user's own MuJoCo.

:func:`write_mjcf` writes the scene the replay simulates (:func:`~warpskill.robot.replay_mujoco.build_spec`:
the Panda at its base pose with its position actuators, the table, the static boxes, the
object as a free body at its start) with ``MjSpec.to_xml``. The Panda's collision meshes are
copied into a folder beside the file (``SCENE_meshes/`` for ``SCENE.xml``) and referenced
relative to it, so the file and its folder can be moved together and load anywhere with
``mujoco.MjModel.from_xml_path``.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from warpskill.contract.reconstruction import Reconstruction
from warpskill.robot.replay_mujoco import build_spec

__all__ = ["write_mjcf"]


def write_mjcf(path: str | Path, recon: Reconstruction, base: np.ndarray) -> Path:
    """Write the scene of ``recon`` with the Panda's base at ``base`` (4, 4) as MJCF to ``path``.

    Returns:
        The path written; the meshes lie in ``<stem>_meshes/`` beside it.
    """
    path = Path(path)
    spec = build_spec(recon, base)
    spec.compile()  # to_xml writes the compiled spec; compiling also checks that every mesh loads
    source = Path(spec.compiler.meshdir)
    meshes = path.with_name(f"{path.stem}_meshes")
    meshes.mkdir(parents=True, exist_ok=True)
    for mesh in spec.meshes:
        shutil.copyfile(source / mesh.file, meshes / mesh.file)
    spec.compiler.meshdir = str(meshes.resolve())  # to_xml compiles again: the copies must be found
    absolute = f'meshdir="{spec.compiler.meshdir}"'
    xml = spec.to_xml()
    if absolute not in xml:
        raise RuntimeError(f"MjSpec.to_xml wrote no {absolute}: cannot make the mesh folder relative")
    path.write_text(xml.replace(absolute, f'meshdir="{meshes.name}"'))  # relative to the file's folder
    return path
