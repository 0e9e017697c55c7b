"""``warpskill view``: a results folder as a Rerun recording (the 3D scene, the masks, the plots)."""

from __future__ import annotations

import sys
from pathlib import Path

__all__ = ["register"]


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
    from warpskill.visual import view_folder

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
