"""A Rerun recording of a reconstruction, its demonstration and the robot's replay, to see it in 3D.

:func:`view` writes one ``.rrd`` file (open it with ``rerun scene.rrd``) or serves it to
Rerun's web viewer; :func:`view_folder` does the same for a folder written by
``warpskill demo`` / ``optimize`` / ``replay`` (``warpskill view OUT/``). The entity tree,
units and frames are described in ``docs/viewer.md``; :mod:`.rerun_scene` computes what is
shown, :mod:`.rerun_entities` logs it.

Everything is on two timelines: ``time`` (seconds, ``t[k] = k / fps`` of the
reconstruction's frame k) and ``frame`` (the index k). World coordinates are those of
``FORMATS.md``: right-handed, z up, the ground is z = 0, metres.

Needs the optional package ``rerun-sdk`` (``pip install -e ".[viewer]"``), imported on
first use, so importing this module works without it.
"""

from __future__ import annotations

import os
import time
import urllib.parse
import uuid
from pathlib import Path
from typing import TYPE_CHECKING

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import Reconstruction, ReconstructionError
from warpskill.contract.replay import Replay
from warpskill.visual.rerun_entities import blueprint, log_scene
from warpskill.visual.rerun_scene import SceneData, prepare_scene

if TYPE_CHECKING:
    from warpskill.robot.plan import RobotPlan

__all__ = ["APPLICATION_ID", "INSTALL_HINT", "WEB_PORT", "view", "view_folder"]

APPLICATION_ID = "warpskill"
"""Rerun application id of every recording written here."""

WEB_PORT = 9090
"""HTTP port of the web viewer started by ``serve=True`` (the recording's gRPC server uses Rerun's 9876)."""

INSTALL_HINT = 'pip install -e ".[viewer]"  (or: pip install rerun-sdk)'
"""How to install what the recording needs."""


def view(
    recon: Reconstruction,
    demo: Demonstration | None = None,
    plan: RobotPlan | None = None,
    replay: Replay | None = None,
    *,
    path: str | os.PathLike = "scene.rrd",
    serve: bool = False,
) -> Path:
    """Write a Rerun recording of ``recon`` (and, when given, its demonstration and robot replay).

    The recording has the scene in world coordinates (z up, metres): ground plane, camera
    (pinhole with ``recon.camera_K``, placed by ``camera_height`` and ``camera_elevation``)
    with the demonstration's masks and the reconstruction's rendered silhouettes as label
    images, the hand cylinder (coloured by ``grasped``), the object and static boxes, their
    paths, and the grasp signals as plots. With ``replay``, the simulated object and TCP
    path. With ``plan``, the Panda's links (collision shapes) follow the replay's simulated
    joints (without ``replay``, the plan's), at the reconstruction's frame rate from the
    plan's ``start_time``; robot frame k is at ``time`` k / fps. Entity paths: ``docs/viewer.md``.

    Args:
        recon: the reconstruction (N frames).
        demo: the demonstration it was fitted to: N frames of the same image size and
            intrinsics; None for none.
        plan: the robot plan made for ``recon`` (:func:`warpskill.robot.retarget`); None for
            no robot.
        replay: the plan's replay (:func:`warpskill.robot.replay` or :meth:`Replay.load`);
            None for none.
        path: the ``.rrd`` file to write (parent folders are created); written atomically.
        serve: also serve the recording to Rerun's web viewer, print its URL and block
            until Ctrl-C.

    Returns:
        The path of the written ``.rrd`` file.

    Raises:
        TypeError: an argument of the wrong type.
        ValueError: ``demo`` or ``replay`` disagrees with ``recon`` (frame count, image
            size, intrinsics, frame rate), or ``replay`` with ``plan``.
        ModuleNotFoundError: ``rerun-sdk`` (or, for a plan, MuJoCo) is not installed; the
            message says what to install.
    """
    rr = _import_rerun()
    scene = prepare_scene(recon, demo, plan, replay)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    recording_id = str(uuid.uuid4())
    layout = blueprint(scene)
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
    try:
        rec.save(tmp, default_blueprint=layout)
        log_scene(rec, scene)
        rec.flush()
        rec.disconnect()
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    if serve:
        _serve(rr, scene, layout, recording_id)
    return path


def view_folder(folder: str | os.PathLike, *, path: str | os.PathLike | None = None, serve: bool = False) -> Path:
    """Record whatever of a results folder exists, as :func:`view` does.

    Reads ``reconstruction.npz`` (required), and if present ``demonstration.npz`` (written
    by ``warpskill demo``), ``plan.npz`` and ``replay.npz`` (``warpskill demo`` /
    ``retarget`` / ``replay``); the arm follows the replay's simulated ``joints``. The robot
    is skipped, with a note, when MuJoCo or the Panda model (extra ``robot``) is not
    installed; a replay file without ``joints`` (written before they were stored) likewise.

    Args:
        folder: the results folder.
        path: the ``.rrd`` to write; default ``folder/scene.rrd``.
        serve: as in :func:`view`.

    Returns:
        The path of the written ``.rrd`` file.

    Raises:
        FileNotFoundError: ``folder`` or its ``reconstruction.npz`` does not exist.
        NotADirectoryError: ``folder`` is a file.
        ValueError: a file that breaks its format, or files that disagree (see :func:`view`).
    """
    folder = Path(folder)
    if not folder.exists():
        raise FileNotFoundError(f"{folder}: no such folder")
    if not folder.is_dir():
        raise NotADirectoryError(f"{folder}: not a folder (expected a results folder with reconstruction.npz)")
    recon_path = folder / "reconstruction.npz"
    if not recon_path.is_file():
        raise FileNotFoundError(f"{recon_path}: not found (run 'warpskill optimize' or 'warpskill demo' first)")
    _import_rerun()  # say what to install before reading anything
    recon = Reconstruction.load(recon_path)
    demo = Demonstration.load(folder / "demonstration.npz") if (folder / "demonstration.npz").is_file() else None
    replay = None
    if (folder / "replay.npz").is_file():
        try:
            replay = Replay.load(folder / "replay.npz")
        except ReconstructionError as error:
            if "missing key" not in str(error):
                raise
            print(f"replay skipped: {error} (rerun 'warpskill replay')")
    plan = None
    if (folder / "plan.npz").is_file():
        from warpskill.robot.plan import RobotPlan
        from warpskill.robot.kinematics import link_shapes

        plan = RobotPlan.load(folder / "plan.npz")
        try:
            link_shapes()  # loads the Panda's model: MuJoCo and example-robot-data
        except (ImportError, RuntimeError) as error:
            print(f"robot skipped: {error}")
            plan = None
    return view(recon, demo, plan, replay, path=folder / "scene.rrd" if path is None else path, serve=serve)


def _serve(rr, scene: SceneData, layout, recording_id: str) -> None:
    """Serve the scene over gRPC with Rerun's web viewer; print the URL; block until Ctrl-C."""
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
    uri = rec.serve_grpc(default_blueprint=layout)
    log_scene(rec, scene)
    rec.flush()
    rr.serve_web_viewer(web_port=WEB_PORT, open_browser=False, connect_to=uri)
    url = f"http://localhost:{WEB_PORT}/?url={urllib.parse.quote(uri, safe=':/')}"
    print(f"Rerun web viewer: {url}  (gRPC: {uri}; Ctrl-C to stop)", flush=True)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        rec.disconnect()


def _import_rerun():
    """``rerun`` (the rerun-sdk package), or a ModuleNotFoundError saying how to install it."""
    try:
        import rerun
    except ModuleNotFoundError as error:
        if error.name not in ("rerun", "rerun_bindings"):
            raise
        raise ModuleNotFoundError(f"the 3D viewer needs rerun-sdk: {INSTALL_HINT}", name="rerun") from None
    return rerun
