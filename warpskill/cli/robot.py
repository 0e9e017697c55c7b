"""``warpskill retarget`` and ``replay``: a reconstruction to a Panda plan, and the plan simulated."""

from __future__ import annotations

from pathlib import Path

from warpskill.cli.common import (
    add_placement_options,
    placement,
    report,
    save_plan,
)

__all__ = ["register"]


def register(commands) -> None:
    """Add ``retarget`` and ``replay`` to the ``commands`` sub-parsers."""
    retarget = commands.add_parser("retarget", help="plan a Franka Panda motion for a reconstruction (placo)")
    retarget.add_argument("reconstruction", type=Path, help="reconstruction .npz (FORMATS.md)")
    retarget.add_argument("-o", "--out", type=Path, required=True, help="plan .npz (a .csv is written beside it)")
    add_placement_options(retarget)
    retarget.add_argument("--object-size", type=float, nargs=3, default=None, metavar=("X", "Y", "Z"),
                          help="the robot's object [m] (default: the reconstructed cuboid, or one that fits the "
                               "gripper); the demonstrated centre path is kept")
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


def _retarget(args) -> int:
    from warpskill.contract import Reconstruction
    from warpskill.robot import retarget

    plan = retarget(Reconstruction.load(args.reconstruction), placement=placement(args),
                    object_size=args.object_size, static_sizes=args.static_size, keep_size=args.keep_size)
    save_plan(plan, args.out)
    return 0


def _replay(args) -> int:
    from warpskill.robot import prefer_headless_gl

    prefer_headless_gl()
    from warpskill.contract import Reconstruction
    from warpskill.robot import RobotPlan, record, replay

    recon = Reconstruction.load(args.reconstruction)
    plan = RobotPlan.load(args.plan)
    args.out.mkdir(parents=True, exist_ok=True)
    result = replay(plan, recon, engine=args.engine)
    result.save(args.out / "replay.npz")
    print(f"replay: {args.out / 'replay.npz'} ({args.engine}, {result.replay_time:.2f} s)")
    if args.video:
        print(f"video: {record(plan, plan.scene(recon), result, args.out)}")
    report(result.reconstruction, result.evaluation.action)
    return 0 if result.success else 3
