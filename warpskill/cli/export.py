"""``warpskill export``: the robot's scene (or its data) in other tools' formats.

    warpskill export mjcf SCENE.xml RECON [--object-at X Y YAW --static-at X Y YAW ...]
                                          [--object-size X Y Z] [--plan PLAN | --offset X Y --yaw DEG]
    warpskill export lerobot OUT RECON... [--episodes N] [--fps F] [--image-size W H] [--cameras front top]
                                          [--seed S] [--keep-failures] [--attempts-per-episode K]
"""

from __future__ import annotations

import signal
import sys
from pathlib import Path

from warpskill import robot  # a lazy package: its names (placo, MuJoCo) load on first use
from warpskill.cli.common import Refused, add_placement_options, placement
from warpskill.cli.robot import add_layout_options, layout_from, refused
from warpskill.contract import LayoutError, Reconstruction

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
    lerobot = formats.add_parser("lerobot", help="rollouts in random layouts as a LeRobot v3.0 dataset, with labels")
    lerobot.add_argument("out", type=Path, help="the dataset folder to write (absent or empty; written whole or not "
                                                "at all)")
    lerobot.add_argument("reconstructions", type=Path, nargs="+", help="reconstruction .npz files (docs/formats.md)")
    lerobot.add_argument("--episodes", type=int, default=50, help="successful rollouts per skill (default 50)")
    lerobot.add_argument("--fps", type=int, default=None, help="frame rate [1/s] (default: the first reconstruction's)")
    lerobot.add_argument("--image-size", type=int, nargs=2, default=[128, 128], metavar=("W", "H"),
                         help="camera frames W x H px, even (default 128 128)")
    lerobot.add_argument("--cameras", nargs="+", default=["front", "top"], help="fixed cameras: front and/or top")
    lerobot.add_argument("--seed", type=int, default=0, help="seed of the random layouts (same seed, same dataset)")
    lerobot.add_argument("--keep-failures", action="store_true",
                         help="also write the failed replays among the layouts tried, labelled next.success false")
    lerobot.add_argument("--attempts-per-episode", type=int, default=4,
                         help="a skill's budget: EPISODES x this many layouts planned and replayed (default 4)")
    lerobot.add_argument("--quiet", action="store_true", help="no progress bar or per-skill lines while it runs")
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
    from warpskill.export import write_mjcf

    print(f"mjcf: {write_mjcf(args.scene, scene, base)}")
    return 0


def _carried(recon, layout):
    """``recon``'s skill carried to ``layout``; ``recon`` itself without one."""
    return recon if layout is None else robot.apply_skill(robot.skill_from(recon), layout)


def _lerobot(args) -> int:
    from warpskill.export import ExportError, ExportRequest, export_lerobot  # optional extra (pyarrow, av)

    robot.prefer_headless_gl()
    request = ExportRequest(episodes=args.episodes, fps=args.fps, image_size=tuple(args.image_size),
                            cameras=tuple(args.cameras), seed=args.seed, keep_failures=args.keep_failures,
                            attempts_per_episode=args.attempts_per_episode)
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        summary = export_lerobot(args.out, args.reconstructions, request, progress=not args.quiet)
    except ExportError as error:
        raise Refused(f"export lerobot: {error}; nothing written") from None
    except KeyboardInterrupt:
        print(f"export lerobot: interrupted; {args.out} left as it was", file=sys.stderr)
        return 130
    except Exception as error:  # noqa: BLE001 - any failure: say that OUT is untouched, in one line
        print(f"export lerobot: failed ({type(error).__name__}: {error}); {args.out} left as it was", file=sys.stderr)
        return 1
    if args.quiet:  # the per-skill lines were not shown while it ran
        for skill in summary.skills:
            print(skill.line())
    if not summary.episodes:
        print(f"export lerobot: no skill gave an episode; nothing written to {args.out}", file=sys.stderr)
        return 2
    given = sum(not skill.left_out for skill in summary.skills)
    print(f"lerobot: {args.out}: {summary.episodes} episodes from {given} of {len(summary.skills)} skills in "
          f"{summary.seconds:.0f} s ({summary.cpu_seconds:.0f} CPU s)")
    return 0


def _interrupt(signum, frame) -> None:
    """SIGTERM as Ctrl-C: the export stops, its temporary folder is removed."""
    raise KeyboardInterrupt
