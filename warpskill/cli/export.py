"""``warpskill export``: the robot's scene (or its data) in other tools' formats.

    warpskill export mjcf SCENE.xml RECON [--object-at X Y YAW --static-at X Y YAW ...]
                                          [--object-size X Y Z] [--plan PLAN | --offset X Y --yaw DEG]
    warpskill export lerobot OUT RECON... [--episodes N] [--fps F] [--size PX] [--cameras front top]
"""

from __future__ import annotations

from pathlib import Path

from warpskill import robot  # a lazy package: its names (placo, MuJoCo) load on first use
from warpskill.cli.common import add_placement_options, placement
from warpskill.cli.robot import add_layout_options, layout_from, refused
from warpskill.contract import LayoutError, Reconstruction, skill_from

__all__ = ["register"]


def register(commands) -> None:
    """Add ``export`` (and its formats) to the ``commands`` sub-parsers."""
    export = commands.add_parser("export", help="the robot's scene in other tools' formats")
    formats = export.add_subparsers(title="formats")
    mjcf = formats.add_parser("mjcf", help="the table, the cuboids and the Panda as one MJCF file (MuJoCo)")
    mjcf.add_argument("scene", type=Path, help="the MJCF file to write (its meshes go to SCENE_meshes/ beside it)")
    mjcf.add_argument("reconstruction", type=Path, help="reconstruction .npz (docs/formats.md)")
    add_layout_options(mjcf)
    mjcf.add_argument("--object-size", type=float, nargs=3, default=None, metavar=("X", "Y", "Z"),
                      help="the object's edge lengths [m] in the layout (default: the reconstructed cuboid)")
    mjcf.add_argument("--plan", type=Path, default=None,
                      help="take the Panda's base pose (and, without layout options, the layout) from this plan")
    add_placement_options(mjcf)
    mjcf.set_defaults(run=_mjcf)
    lerobot = formats.add_parser("lerobot", help="successful rollouts in random layouts as a LeRobot v3.0 dataset")
    lerobot.add_argument("out", type=Path, help="the dataset folder to write (empty or absent)")
    lerobot.add_argument("reconstructions", type=Path, nargs="+", help="reconstruction .npz files (docs/formats.md)")
    lerobot.add_argument("--episodes", type=int, default=50, help="successful rollouts per reconstruction (default 50)")
    lerobot.add_argument("--fps", type=int, default=None, help="frame rate [1/s] (default: the reconstruction's)")
    lerobot.add_argument("--size", type=int, default=128, help="camera frames SIZE x SIZE px (even; default 128)")
    lerobot.add_argument("--cameras", nargs="+", default=["front", "top"], help="fixed cameras: front and/or top")
    lerobot.add_argument("--seed", type=int, default=0, help="seed of the random layouts")
    lerobot.set_defaults(run=_lerobot)


def _mjcf(args) -> int:
    recon = Reconstruction.load(args.reconstruction)
    try:
        layout = layout_from(args, recon)
        where = placement(args)
        if args.plan is not None:  # the plan's base, and its scene unless a layout is given
            plan = robot.RobotPlan.load(args.plan)
            scene, base = plan.scene(recon) if layout is None else _carried(recon, layout), plan.base
        elif where != "auto":  # a fixed base: no planning
            scene = _carried(recon, layout)
            base = robot.make_scene(scene, where).base
        else:  # the base pose the plan would take
            plan = robot.retarget(recon, layout=layout)
            scene, base = plan.scene(recon), plan.base
    except LayoutError as error:
        return refused(error)
    print(f"mjcf: {robot.write_mjcf(args.scene, scene, base)}")
    return 0


def _carried(recon, layout):
    """``recon``'s skill carried to ``layout``; ``recon`` itself without one."""
    return recon if layout is None else skill_from(recon).apply(layout)


def _lerobot(args) -> int:
    from warpskill.export import export_lerobot  # optional extra: export (pyarrow)

    robot.prefer_headless_gl()
    summary = export_lerobot(args.out, args.reconstructions, episodes=args.episodes, fps=args.fps, size=args.size,
                             cameras=args.cameras, seed=args.seed)
    total = sum(summary["episodes"].values())
    print(f"lerobot: {args.out}: {total} episodes from {sum(summary['attempts'].values())} layouts in "
          f"{summary['seconds']:.0f} s ({summary['cpu_seconds']:.0f} CPU s)")
    return 0
