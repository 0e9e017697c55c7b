"""The ``warpskill`` command line.

    warpskill demo [-o OUT]                       synthesise, reconstruct, picture, evaluate, plan, replay
    warpskill prepare VIDEO (--polygons F|--masks D|--labels D|--boxes F --video-id ID) --action A -o DEMO.npz
                                                  a recording to a demonstration and a contact sheet
    warpskill run VIDEO (same inputs) --action A -o OUT
                                                  prepare, optimize, retarget and replay; resumable
    warpskill optimize DEMO.npz -o OUT            one demonstration to OUT/reconstruction.npz
    warpskill optimize A.npz B.npz ... -o OUT     several, side by side: OUT/A/, OUT/B/, ...
    warpskill evaluate RECON.npz [--action A]     the paper's success criteria
    warpskill retarget RECON.npz -o PLAN.npz      Panda plan (placo); also PLAN.csv
    warpskill replay PLAN.npz RECON.npz -o OUT    simulate the plan: OUT/replay.npz + success
    warpskill retarget RECON.npz -o PLAN.npz --object-at X Y YAW [--static-at X Y YAW ...]
                                                  the skill carried to another layout (yaw in degrees)
    warpskill export mjcf SCENE.xml RECON.npz     the table, the cuboids and the Panda as MJCF (same layout options)
    warpskill export lerobot OUT RECON... [--episodes N]
                                                  successful rollouts in random layouts as a LeRobot dataset
    warpskill view OUT [-o SCENE.rrd] [--serve]   a Rerun recording of a results folder (3D scene)
    warpskill app [-o DIR] [--port N]             a local web page: upload, outline, run, see the results
    warpskill bench kernels [--device cpu|cuda]   Warp kernel microbenchmarks
    warpskill bench speed [--device cpu|cuda]     Warp engine vs plain-Torch reference, per iteration
    warpskill bench synthetic [--seeds N]         the paper's success table on synthetic data
    warpskill bench robot [--source truth|optimised] [--engines mujoco newton]
                                                  plan and replay the 9 actions x N seeds on the Panda
    warpskill bench generalize RECON... [--layouts N] [--engines mujoco newton]
                                                  each skill in random layouts: planned, succeeded, robust
    warpskill bench something-else --annotations A.json --phases P.csv --actions A.csv [-o OUT]
                                                  the same table on annotated real videos
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import sys

from warpskill.cli import app, bench, export, pipeline, prepare, robot, run, view
from warpskill.cli.common import Refused
from warpskill.contract import ResultsFolderError

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``warpskill`` console script; returns the exit status."""
    parser = _parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "run"):
        parser.print_help()
        return 2
    from warpskill.warp_log import configure_warp_log  # imports Warp: not for --help

    configure_warp_log(args.verbose)
    set_torch_threads(args.torch_threads)
    try:
        with console_log():
            return args.run(args) or 0
    except Refused as error:  # understood, cannot be done: one line, status 2
        print(f"warpskill: error: {error}", file=sys.stderr)
        return 2
    except (ValueError, FileNotFoundError, ResultsFolderError) as error:  # bad input, a full disk: one clear line
        print(f"warpskill: error: {error}", file=sys.stderr)
        return 1


@contextlib.contextmanager
def console_log():
    """While a command runs, the library's progress and warnings (the ``warpskill`` loggers, INFO and
    up) are shown on the standard output of the moment (pytest swaps it), one plain line each, as
    the command's own lines."""
    logger, handler = logging.getLogger("warpskill"), logging.StreamHandler(sys.stdout)
    level = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


def set_torch_threads(requested: int | None) -> None:
    """Torch's CPU threads for this process: ``requested``; None: one, unless ``OMP_NUM_THREADS``
    chooses.

    The optimiser runs many small Torch operations: alone, one thread is as fast as two, and two
    processes side by side with two threads each on two cores each ran five times slower.
    """
    if requested is None and "OMP_NUM_THREADS" in os.environ:
        return
    threads = requested or 1
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(threads)
    else:  # read when Torch is imported: commands without Torch do not pay for its import
        os.environ["OMP_NUM_THREADS"] = str(threads)


def _positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="warpskill", description="Learn a manipulation skill from one video.")
    parser.add_argument("--verbose", action="store_true",
                        help="show Warp's messages (module loads and compiles); before the command: warpskill --verbose demo")
    parser.add_argument("--torch-threads", type=_positive, metavar="N",
                        help="Torch's CPU threads (default: 1, or OMP_NUM_THREADS where set); before the command")
    commands = parser.add_subparsers(title="commands")
    for module in (pipeline, prepare, run, robot, export, bench, view, app):
        module.register(commands)
    return parser
