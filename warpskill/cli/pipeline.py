"""``warpskill demo``, ``optimize`` and ``evaluate``: a demonstration to a judged reconstruction."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from warpskill import robot, visual  # lazy packages: their names (MuJoCo, torch, Warp) load on first use
from warpskill.cli import common
from warpskill.contract import (
    Demonstration,
    DemonstrationError,
    Reconstruction,
    ResultsFolder,
    at_optimiser_rate,
    evaluate,
    frame_stride,
)

__all__ = ["register"]


def register(commands) -> None:
    """Add ``demo``, ``optimize`` and ``evaluate`` to the ``commands`` sub-parsers."""
    demo = commands.add_parser("demo", help="run the whole pipeline on an embedded synthetic demonstration")
    demo.add_argument("-o", "--out", type=Path, default=Path("warpskill-out/demo"), help="output folder")
    demo.add_argument("--action", default="put_onto", help="which action to synthesise (default: put_onto)")
    common.add_optimize_options(demo)
    common.add_robot_step_options(demo)
    demo.set_defaults(run=_demo)

    optimize = commands.add_parser("optimize", help="reconstruct demonstration .npz files (several: together)")
    optimize.add_argument("demos", type=Path, nargs="+", metavar="demo",
                          help="demonstration .npz (docs/formats.md); several are optimised side by side")
    optimize.add_argument("-o", "--out", type=Path, required=True,
                          help="output folder (with several demonstrations: OUT/<file name>/ each)")
    optimize.add_argument("--no-pictures", action="store_true", help="skip the pictures")
    optimize.add_argument("--workers", type=int, metavar="N",
                          help="spread the demonstrations over N Ray workers (one per core; on CUDA one per GPU): "
                               "OUT/<name>/ each, finished ones skipped on a rerun (needs the cluster extra)")
    optimize.add_argument("--ray-address", metavar="ADDR",
                          help="join this Ray cluster instead of starting a local one (default: $RAY_ADDRESS)")
    common.add_optimize_options(optimize)
    optimize.set_defaults(run=_optimize)

    evaluate = commands.add_parser("evaluate", help="check a reconstruction against the paper's success criteria")
    evaluate.add_argument("reconstruction", type=Path, help="reconstruction .npz (docs/formats.md)")
    evaluate.add_argument("--action", help="action name (default: the one stored in the file)")
    evaluate.add_argument("--mode", choices=("strict", "original"), default="strict")
    evaluate.set_defaults(run=_evaluate)


@common.holding_out
def _demo(args) -> int:
    from warpskill.synthetic import make_demonstration  # torch and Warp: only for this command

    options = common.optimize_options(args)
    robot.prefer_headless_gl()
    demo = make_demonstration(args.action, seed=options.seed)
    keeper = ResultsFolder(args.out)
    print(f"demonstration: {keeper.save(demo, keeper.demonstration)} ({args.action}, {demo.num_frames} frames)")
    [recon] = common.reconstruct([demo], [args.out], keeper.checkpoint, options, quiet=args.quiet)
    if not common.robot_steps_wanted(args):
        return 0
    plan = common.plan_robot(recon, args)
    if plan is None:
        return 0
    common.save_plan(plan, keeper.plan)
    result = robot.replay(plan, recon)
    print(f"replay: {keeper.save(result, keeper.replay)} (mujoco, {result.replay_time:.2f} s); "
          f"picture: {robot.record(plan, recon, result, args.out)}")
    common.save_scene(recon, demo, args.out, plan, result, quiet=True)  # scene.rrd again, with the robot
    common.report(result.reconstruction, args.action)
    return 0


def _optimize(args) -> int:
    options = common.optimize_options(args)
    stems = [path.stem for path in args.demos]
    if len(set(stems)) < len(stems):
        raise ValueError("demonstration files must have different names: each gets OUT/<name>/")
    if args.workers is not None or args.ray_address:
        from warpskill.cluster import INSTALL_HINT, ray_available  # torch and Warp: only with --workers

        if ray_available():
            return _optimize_on_ray(args, options, stems)
        print(f"--workers needs Ray, which is not installed ({INSTALL_HINT}): optimising serially")
    demos = [Demonstration.load(path) for path in args.demos]
    folders = [args.out] if len(demos) == 1 else [args.out / stem for stem in stems]
    common.reconstruct(demos, folders, ResultsFolder(args.out).checkpoint, options, quiet=args.quiet, pictures=not args.no_pictures)
    return 0


def _optimize_on_ray(args, options, stems: list[str]) -> int:
    """``optimize --workers N``: each demonstration a Ray task into OUT/<name>/; one progress bar, a summary."""
    from warpskill.cluster import optimize_folder  # torch and Warp: only with --workers

    if args.workers is not None and args.workers < 1:
        raise ValueError("--workers must be at least 1")
    if not args.ray_address:
        from warpskill.engine import resolve_device  # torch and Warp: only with --workers

        resolve_device(options.device)  # a bad device is one error line, not one failure per demonstration
    summary = optimize_folder(
        {stem: _fitted(path) for stem, path in zip(stems, args.demos)}, args.out, options, workers=args.workers,
        address=args.ray_address,
        progress=not args.quiet, postprocess=None if args.no_pictures else _pictures,
    )
    for outcome in summary.outcomes.values():
        if outcome.ok:
            recon = Reconstruction.load(outcome.reconstruction)
            print(f"reconstruction: {outcome.reconstruction}")
            common.report(recon, str(recon.action) or None)
    print(summary)
    return 1 if summary.failed else 0


def _fitted(path: Path) -> Path | Demonstration:
    """A demonstration file for its Ray task to read, or, of a video well above 12 fps, the frames the
    optimiser fits (:func:`~warpskill.contract.frame_rate.at_optimiser_rate`, as ``optimize`` without
    ``--workers`` fits them); a file that does not read is left to its task, to fail alone."""
    try:
        with np.load(path) as arrays:
            fps = float(arrays["fps"])
        return path if frame_stride(fps) == 1 else at_optimiser_rate(Demonstration.load(path))
    except (OSError, ValueError, KeyError, DemonstrationError):
        return path


def _pictures(recon, demo, folder: Path) -> None:
    """The pictures and 3D scene of one reconstruction (run in its Ray task)."""
    visual.save_pictures(recon, demo, folder)
    common.save_scene(recon, demo, folder, quiet=True)


def _evaluate(args) -> int:
    recon = Reconstruction.load(args.reconstruction)
    action = args.action or str(recon.action) or None
    if not action:
        raise ValueError("the reconstruction names no action: pass --action")
    result = evaluate(recon, action, mode=args.mode)
    for name, ok in result.checks.items():
        margin = result.margins.get(name)
        room = "" if margin is None else f"  ({margin:+.3f} m to its limit)"
        print(f"  {'ok  ' if ok else 'FAIL'} {name}{room}")
    print(f"{action}: {'success' if result.success else 'failure'}")
    for line in common.hypothesis_lines(recon.judgements()):
        print(line)
    return 0 if result.success else 3
