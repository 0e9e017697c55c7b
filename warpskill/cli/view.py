"""``warpskill view``: a results folder as a Rerun recording (the 3D scene, the masks, the plots)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from warpskill.contract import Demonstration, Reconstruction, ReconstructionError, Replay, ResultsFolder

__all__ = ["register", "view_folder"]


def register(commands) -> None:
    """Add ``view`` to the ``commands`` sub-parsers."""
    view = commands.add_parser(
        "view",
        help="a results folder as a Rerun recording: the scene in 3D, the masks, the robot (extra 'viewer')",
        description="Write a Rerun recording (.rrd) of a folder written by 'warpskill demo', 'optimize' or "
        "'replay': the reconstructed scene in 3D (z up, metres), the demonstration's masks and the rendered "
        "silhouettes, the grasp plots and, with plan.npz and replay.npz, the Panda and the simulated object. "
        "Open it with: rerun OUT/scene.rrd. Needs rerun-sdk: pip install -e \".[viewer]\".",
    )
    view.add_argument("folder", type=Path,
                      help="results folder: reconstruction.npz; demonstration.npz, plan.npz, replay.npz if present")
    view.add_argument("-o", "--out", type=Path, default=None, help="the .rrd to write (default: FOLDER/scene.rrd)")
    view.add_argument("--serve", action="store_true",
                      help="also serve it to Rerun's web viewer: prints the URL, runs until Ctrl-C")
    view.set_defaults(run=_view)


def _view(args) -> int:
    try:
        path = view_folder(args.folder, path=args.out, serve=args.serve)
    except ModuleNotFoundError as error:
        if error.name != "rerun":
            raise
        print(f"warpskill: error: {error}", file=sys.stderr)
        return 1
    except NotADirectoryError as error:
        print(f"warpskill: error: {error}", file=sys.stderr)
        return 1
    print(f"scene: {path} (open with: rerun {path})")
    return 0


def view_folder(folder: str | os.PathLike, *, path: str | os.PathLike | None = None, serve: bool = False) -> Path:
    """Record whatever of a results folder exists, as :func:`warpskill.visual.view` does.

    Reads ``reconstruction.npz`` (required), and if present ``demonstration.npz`` (written
    by ``warpskill demo``), ``plan.npz`` and ``replay.npz`` (``warpskill demo`` /
    ``retarget`` / ``replay``); the arm follows the replay's simulated ``joints``. The robot
    is skipped, with a note, when MuJoCo or the Panda model (extra ``robot``) is not
    installed; a replay file without ``joints`` (written before they were stored) likewise.

    Args:
        folder: the results folder.
        path: the ``.rrd`` to write; default ``folder/scene.rrd``.
        serve: as in :func:`warpskill.visual.view`.

    Returns:
        The path of the written ``.rrd`` file.

    Raises:
        FileNotFoundError: ``folder`` or its ``reconstruction.npz`` does not exist.
        NotADirectoryError: ``folder`` is a file.
        ValueError: a file that breaks its format, or files that disagree (see :func:`warpskill.visual.view`).
    """
    from warpskill.visual import import_rerun, view  # torch and Warp: loaded for this command only

    folder = Path(folder)
    if not folder.exists():
        raise FileNotFoundError(f"{folder}: no such folder")
    if not folder.is_dir():
        raise NotADirectoryError(f"{folder}: not a folder (expected a results folder with reconstruction.npz)")
    keeper = ResultsFolder(folder)
    recon_path = keeper.reconstruction
    if not recon_path.is_file():
        raise FileNotFoundError(f"{recon_path}: not found (run 'warpskill optimize' or 'warpskill demo' first)")
    import_rerun()  # say what to install before reading anything
    recon = Reconstruction.load(recon_path)
    demo = Demonstration.load(keeper.demonstration) if keeper.demonstration.is_file() else None
    replay = _replay(keeper.replay)
    robot = _robot(keeper.plan, float(recon.fps), replay)
    return view(recon, demo, robot, replay, path=folder / "scene.rrd" if path is None else path, serve=serve)


def _replay(path: Path) -> Replay | None:
    """The replay at ``path``; None, with a note, where it is missing or has no joints."""
    if not path.is_file():
        return None
    try:
        return Replay.load(path)
    except ReconstructionError as error:
        if "missing key" not in str(error):
            raise
        print(f"replay skipped: {error} (rerun 'warpskill replay')")
        return None


def _robot(plan_path: Path, fps: float, replay: Replay | None):
    """The Panda's track of the plan at ``plan_path``; None, with a note, without the robot extra."""
    if not plan_path.is_file():
        return None
    from warpskill.robot import RobotPlan, robot_track  # placo / MuJoCo: only for a folder with a plan

    try:
        return robot_track(RobotPlan.load(plan_path), fps, replay)
    except (ImportError, RuntimeError) as error:
        print(f"robot skipped: {error}")
        return None
