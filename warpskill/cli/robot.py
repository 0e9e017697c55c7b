"""``warpskill retarget`` and ``replay``: a reconstruction to a Panda plan, and the plan simulated."""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

from warpskill import robot  # a lazy package: its names (placo, MuJoCo) load on first use
from warpskill.cli import common
from warpskill.contract import LayoutError, Reconstruction, ResultsFolder

__all__ = ["register"]


def register(commands) -> None:
    """Add ``retarget`` and ``replay`` to the ``commands`` sub-parsers."""
    retarget = commands.add_parser("retarget", help="plan a Franka Panda motion for a reconstruction (placo)")
    retarget.add_argument("reconstruction", type=Path, help="reconstruction .npz (docs/formats.md)")
    retarget.add_argument("-o", "--out", type=Path, required=True, help="plan .npz (a .csv is written beside it)")
    common.add_placement_options(retarget)
    add_layout_options(retarget)
    retarget.add_argument("--object-size", type=float, nargs=3, default=None, metavar=("X", "Y", "Z"),
                          help="the robot's object [m] (default: the reconstructed cuboid, or one that fits the "
                               "gripper); the demonstrated centre path is kept; with --object-at or --static-at, "
                               "the layout's object")
    retarget.add_argument("--static-size", type=float, nargs=3, action="append", default=None,
                          metavar=("X", "Y", "Z"), help="a static object's size [m]; once per static object")
    retarget.add_argument("--keep-size", action="store_true",
                          help="refuse an object too wide for the gripper instead of substituting one that fits")
    retarget.set_defaults(run=_retarget)

    replay = commands.add_parser("replay", help="simulate a robot plan and check the action's success")
    replay.add_argument("plan", type=Path, help="plan .npz from 'warpskill retarget'")
    replay.add_argument("reconstruction", type=Path, help="the reconstruction .npz the plan was made for")
    replay.add_argument("-o", "--out", type=Path, required=True, help="output folder (replay.npz)")
    replay.add_argument("--engine", choices=("mujoco", "newton"), default="mujoco")
    replay.add_argument("--video", action="store_true", help="also write replay.mp4 (or replay.png without a renderer)")
    replay.set_defaults(run=_replay)


def add_layout_options(parser) -> None:
    """``--object-at`` and ``--static-at``: carry the skill to another layout (with ``--object-size``)."""
    parser.add_argument("--object-at", type=float, nargs=3, default=None, metavar=("X", "Y", "YAW"),
                        help="run the skill with the object starting here: world x, y [m] and yaw [deg] "
                             "(default: where the demonstration had it)")
    parser.add_argument("--static-at", type=float, nargs=3, action="append", default=None,
                        metavar=("X", "Y", "YAW"),
                        help="a static box here: world x, y [m], yaw [deg]; once per static box, in the "
                             "reconstruction's order (default: where the demonstration had them)")


def layout_from(args, recon):
    """The :class:`~warpskill.contract.skill.Layout` of ``--object-at``, ``--static-at`` and
    ``--object-size`` (degrees to radians) for ``recon``'s skill, or None where none is given."""
    if args.object_at is None and args.static_at is None:
        return None
    layout = robot.demonstrated_layout(robot.skill_from(recon))
    if args.object_at is not None:
        x, y, yaw = args.object_at
        layout = dataclasses.replace(layout, object=(x, y, math.radians(yaw)))
    if args.static_at is not None:
        layout = dataclasses.replace(layout, statics=tuple((x, y, math.radians(yaw)) for x, y, yaw in args.static_at))
    return dataclasses.replace(layout, object_size=args.object_size)


def refused(error) -> int:
    """Print a refused layout's line; the exit status 2."""
    print(f"warpskill: error: {error}", file=sys.stderr)
    return 2


def _retarget(args) -> int:
    recon = Reconstruction.load(args.reconstruction)
    try:
        layout = layout_from(args, recon)
        plan = robot.retarget(recon, layout=layout, placement=common.placement(args), static_sizes=args.static_size,
                        keep_size=args.keep_size, object_size=None if layout is not None else args.object_size)
    except LayoutError as error:
        return refused(error)
    common.save_plan(plan, args.out)
    if layout is not None:
        print(f"layout: {layout.describe()}")
    if str(recon.action):  # what the video teaches, beside the reconstruction (docs/formats.md)
        skill_path = args.reconstruction.with_name("skill.npz")
        robot.skill_from(recon).save(skill_path)
        print(f"skill: {skill_path}")
    return 0


@common.holding_out
def _replay(args) -> int:
    robot.prefer_headless_gl()
    recon = Reconstruction.load(args.reconstruction)
    plan = robot.RobotPlan.load(args.plan)
    args.out.mkdir(parents=True, exist_ok=True)
    result = robot.replay(plan, recon, engine=args.engine)
    keeper = ResultsFolder(args.out)
    print(f"replay: {keeper.save(result, keeper.replay)} ({args.engine}, {result.replay_time:.2f} s)")
    if args.video:
        print(f"video: {robot.record(plan, plan.scene(recon), result, args.out)}")
    common.report(result.reconstruction, result.evaluation.action)
    return 0 if result.success else 3
