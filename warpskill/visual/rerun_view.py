"""A Rerun recording of a reconstruction, its demonstration and the robot's replay, to see it in 3D.

:func:`view` writes one ``.rrd`` file (open it with ``rerun scene.rrd``) or serves it to
Rerun's web viewer (``warpskill view OUT/`` records a results folder). The entity tree,
units and frames are described in ``docs/viewer.md``; :mod:`.rerun_scene` computes what is
shown, :mod:`.rerun_entities` logs it.

Everything is on two timelines: ``time`` (seconds, ``t[k] = k / fps`` of the
reconstruction's frame k) and ``frame`` (the index k). World coordinates are those of
``docs/formats.md``: right-handed, z up, the ground is z = 0, metres.

Needs the optional package ``rerun-sdk`` (``pip install -e ".[viewer]"``), imported on
first use, so importing this module works without it.
"""

from __future__ import annotations

import logging
import os
import time
import urllib.parse
import uuid
from pathlib import Path

import numpy as np

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.replay import Replay
from warpskill.visual.rerun_entities import blueprint, log_scene
from warpskill.visual.rerun_scene import SceneData, prepare_scene

logger = logging.getLogger(__name__)

__all__ = ["APPLICATION_ID", "INSTALL_HINT", "WEB_PORT", "import_rerun", "view"]

APPLICATION_ID = "warpskill"
"""Rerun application id of every recording written here."""

WEB_PORT = 9090
"""HTTP port of the web viewer started by ``serve=True`` (the recording's gRPC server uses Rerun's 9876)."""

INSTALL_HINT = 'pip install -e ".[viewer]"  (or: pip install rerun-sdk)'
"""How to install what the recording needs."""


def view(
    recon: Reconstruction,
    demo: Demonstration | None = None,
    robot=None,
    replay: Replay | None = None,
    *,
    frames: np.ndarray | None = None,
    path: str | os.PathLike = "scene.rrd",
    serve: bool = False,
) -> Path:
    """Write a Rerun recording of ``recon`` (and, when given, its demonstration and robot replay).

    The recording has the scene in world coordinates (z up, metres): ground plane, camera
    (pinhole with ``recon.camera_K``, placed by ``camera_height`` and ``camera_elevation``)
    with the demonstration's video frames, its masks and the reconstruction's rendered
    silhouettes as images, the hand cylinder (coloured by ``grasped``), the object and
    static boxes, their paths, and the grasp signals as plots. With ``replay``, the
    simulated object and TCP path. With ``robot``, the Panda's links (collision shapes) as
    the track has them; robot frame k is at ``time`` k / fps. Entity paths: ``docs/viewer.md``.

    Args:
        recon: the reconstruction (N frames).
        demo: the demonstration it was fitted to: N frames of the same image size and
            intrinsics; None for none.
        robot: the Panda's track at the reconstruction's frame rate
            (:func:`warpskill.robot.robot_track` of the plan and its replay); None for no robot.
        replay: the plan's replay (:func:`warpskill.robot.replay` or :meth:`Replay.load`);
            None for none.
        frames: (N, H, W, 3) uint8 RGB frames of the demonstration's video (what
            :func:`warpskill.data.read_recording` returns beside it); None for none.
        path: the ``.rrd`` file to write (parent folders are created); written atomically.
        serve: also serve the recording to Rerun's web viewer, print its URL and block
            until Ctrl-C.

    Returns:
        The path of the written ``.rrd`` file.

    Raises:
        TypeError: an argument of the wrong type.
        ValueError: ``demo``, ``replay`` or ``frames`` disagree with ``recon`` (frame
            count, image size, intrinsics, frame rate).
        ModuleNotFoundError: ``rerun-sdk`` is not installed; the message says what to install.
    """
    rr = import_rerun()
    scene = prepare_scene(recon, demo, robot, replay, frames)
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


def _serve(rr, scene: SceneData, layout, recording_id: str) -> None:
    """Serve the scene over gRPC with Rerun's web viewer; print the URL; block until Ctrl-C."""
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
    uri = rec.serve_grpc(default_blueprint=layout)
    log_scene(rec, scene)
    rec.flush()
    rr.serve_web_viewer(web_port=WEB_PORT, open_browser=False, connect_to=uri)
    url = f"http://localhost:{WEB_PORT}/?url={urllib.parse.quote(uri, safe=':/')}"
    logger.info("Rerun web viewer: %s  (gRPC: %s; Ctrl-C to stop)", url, uri)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        rec.disconnect()


def import_rerun():
    """``rerun`` (the rerun-sdk package), or a ModuleNotFoundError saying how to install it."""
    try:
        import rerun  # the optional extra "viewer"
    except ModuleNotFoundError as error:
        if error.name not in ("rerun", "rerun_bindings"):
            raise
        raise ModuleNotFoundError(f"the 3D viewer needs rerun-sdk: {INSTALL_HINT}", name="rerun") from None
    return rerun
