"""``warpskill app``: a local web page that runs ``warpskill run`` on a clip (Gradio, extra ``app``)."""

from __future__ import annotations

import os
from pathlib import Path

from warpskill.cli.common import Refused, installed

__all__ = ["register"]


def register(commands) -> None:
    """Add ``app`` to the ``commands`` sub-parsers."""
    parser = commands.add_parser(
        "app", help="a local web page: upload a clip, outline it, run, see and download the results (extra 'app')",
        description="Serve a page (http://127.0.0.1:7860 by default) to upload a clip (a video file or its frames), "
        "outline the object on one frame (two clicks box it, or a proposal), pick the action and run the steps of "
        "'warpskill run', then see the contact sheet, the overlay, the top view and the robot's replay, and "
        "download the results folder. Runs until Ctrl-C. Needs Gradio: pip install -e \".[app]\".",
    )
    parser.add_argument("-o", "--out", type=Path, default=Path("warpskill-out/app"),
                        help="where the uploaded clips and their runs go (default: warpskill-out/app)")
    parser.add_argument("--host", default="127.0.0.1", help="the address to serve on (0.0.0.0: every interface)")
    parser.add_argument("--port", type=int, default=None, help="the port (default: the first free one from 7860)")
    parser.add_argument("--browser", action="store_true", help="open the page in the default browser")
    parser.set_defaults(run=_app)


def _app(args) -> int:
    if not installed("gradio"):
        raise Refused("the page needs Gradio: pip install -e \".[app]\"")
    os.environ.setdefault("GRADIO_ANALYTICS_ENABLED", "False")  # read when Gradio is imported: no calls home
    from warpskill.app import serve

    args.out.mkdir(parents=True, exist_ok=True)
    serve(args.out.resolve(), host=args.host, port=args.port, open_browser=args.browser)
    return 0
