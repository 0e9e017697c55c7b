"""The ``warpskill`` command line.

    warpskill demo [-o OUT]                       synthesise, reconstruct, picture, evaluate, plan, replay
    warpskill optimize DEMO.npz -o OUT            one demonstration to OUT/reconstruction.npz
    warpskill optimize A.npz B.npz ... -o OUT     several, side by side: OUT/A/, OUT/B/, ...
    warpskill evaluate RECON.npz [--action A]     the paper's success criteria
    warpskill retarget RECON.npz -o PLAN.npz      Panda plan (placo); also PLAN.csv
    warpskill replay PLAN.npz RECON.npz -o OUT    simulate the plan: OUT/replay.npz + success
    warpskill bench kernels [--device cpu|cuda]   Warp kernel microbenchmarks
    warpskill bench speed [--device cpu|cuda]     Warp engine vs plain-Torch reference, per iteration
    warpskill bench synthetic [--seeds N]         the paper's success table on synthetic data
    warpskill bench robot [--source truth|optimised] [--engines mujoco newton]
                                                  plan and replay the 9 actions x N seeds on the Panda
    warpskill bench something-else --annotations A.json --phases P.csv --actions A.csv [-o OUT]
                                                  the same table on annotated real videos
"""

from __future__ import annotations

import argparse
import importlib.metadata
import math
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``warpskill`` console script; returns the exit status."""
    parser = _parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "run"):
        parser.print_help()
        return 2
    try:
        return args.run(args) or 0
    except (ValueError, FileNotFoundError) as error:  # bad input: one clear line, no traceback
        print(f"warpskill: error: {error}", file=sys.stderr)
        return 1


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="warpskill", description="Learn a manipulation skill from one video.")
    commands = parser.add_subparsers(title="commands")

    demo = commands.add_parser("demo", help="run the whole pipeline on an embedded synthetic demonstration")
    demo.add_argument("-o", "--out", type=Path, default=Path("warpskill-out/demo"), help="output folder")
    demo.add_argument("--action", default="put_onto", help="which action to synthesise (default: put_onto)")
    demo.add_argument("--no-robot", action="store_true", help="stop after the reconstruction (no Panda plan or replay)")
    _add_optimise_options(demo)
    _add_placement_options(demo)
    demo.set_defaults(run=_demo)

    optimise = commands.add_parser("optimize", help="reconstruct demonstration .npz files (several: together)")
    optimise.add_argument("demos", type=Path, nargs="+", metavar="demo",
                          help="demonstration .npz (FORMATS.md); several are optimised side by side")
    optimise.add_argument("-o", "--out", type=Path, required=True,
                          help="output folder (with several demonstrations: OUT/<file name>/ each)")
    optimise.add_argument("--init-only", action="store_true", help="stop after the physics-free initialisation")
    optimise.add_argument("--no-pictures", action="store_true", help="skip the pictures")
    _add_optimise_options(optimise)
    optimise.set_defaults(run=_optimize)

    evaluate = commands.add_parser("evaluate", help="check a reconstruction against the paper's success criteria")
    evaluate.add_argument("reconstruction", type=Path, help="reconstruction .npz (FORMATS.md)")
    evaluate.add_argument("--action", help="action name (default: the one stored in the file)")
    evaluate.add_argument("--mode", choices=("strict", "original"), default="strict")
    evaluate.set_defaults(run=_evaluate)

    retarget = commands.add_parser("retarget", help="plan a Franka Panda motion for a reconstruction (placo)")
    retarget.add_argument("reconstruction", type=Path, help="reconstruction .npz (FORMATS.md)")
    retarget.add_argument("-o", "--out", type=Path, required=True, help="plan .npz (a .csv is written beside it)")
    _add_placement_options(retarget)
    retarget.set_defaults(run=_retarget)

    replay = commands.add_parser("replay", help="simulate a robot plan and check the action's success")
    replay.add_argument("plan", type=Path, help="plan .npz from 'warpskill retarget'")
    replay.add_argument("reconstruction", type=Path, help="the reconstruction .npz the plan was made for")
    replay.add_argument("-o", "--out", type=Path, required=True, help="output folder (replay.npz)")
    replay.add_argument("--engine", choices=("mujoco", "newton"), default="mujoco")
    replay.add_argument("--video", action="store_true", help="also write replay.mp4 (or replay.png without a renderer)")
    replay.set_defaults(run=_replay)

    bench = commands.add_parser("bench", help="benchmarks").add_subparsers(title="benchmarks")
    kernels = bench.add_parser("kernels", help="Warp kernel microbenchmarks")
    kernels.add_argument("--device", default="cpu", help="cpu or cuda")
    kernels.add_argument("--repeats", type=int, default=5, help="timed repetitions (median reported)")
    kernels.set_defaults(run=_bench_kernels)
    speed = bench.add_parser("speed", help="optimisation iterations: Warp engine vs its plain-Torch reference")
    speed.add_argument("--device", default="cpu", help="cpu, or cuda (then the CPU too)")
    speed.add_argument("--engines", nargs="+", default=["warp", "reference"], help="warp and/or reference")
    speed.add_argument("--repeats", type=int, default=3, help="timed iterations (median reported)")
    speed.add_argument("--full", action="store_true", help="also time warpskill.optimize end to end per engine")
    speed.add_argument("--scaling", action="store_true", help="also time iterations as frames, image size, B grow")
    speed.add_argument("--threads", type=int, help="Torch CPU threads (default: Torch's choice)")
    speed.add_argument("--many", type=int, nargs="+", metavar="B",
                       help="also run warpskill.optimize_many on B synthetic demonstrations: demonstrations per second")
    speed.set_defaults(run=_bench_speed)
    synthetic = bench.add_parser("synthetic", help="the 9 actions x N seeds: the paper's success table")
    synthetic.add_argument("--seeds", type=int, default=3)
    synthetic.add_argument("--noise", default="moderate", help="none, low, moderate or high")
    synthetic.add_argument("--actions", nargs="*", help="a subset of the actions (default: all 9)")
    synthetic.add_argument("-o", "--out", type=Path, help="also write every demonstration and reconstruction here")
    synthetic.add_argument("--device", default="cpu")
    synthetic.add_argument("--iterations", type=int, help="physics-stage iterations (default: the library's)")
    synthetic.set_defaults(run=_bench_synthetic)
    robot = bench.add_parser("robot", help="retarget synthetic reconstructions to the Panda and replay them")
    robot.add_argument("--seeds", type=int, default=3)
    robot.add_argument("--source", choices=("truth", "optimised"), default="truth",
                       help="ground-truth reconstructions, or the optimiser's output on noisy demonstrations")
    robot.add_argument("--engines", nargs="+", choices=("mujoco", "newton"), default=["mujoco"])
    robot.add_argument("--actions", nargs="*", help="a subset of the actions (default: all 9)")
    robot.add_argument("-o", "--out", type=Path, help="keep reconstructions and plans here (reused on a rerun)")
    robot.add_argument("--device", default="cpu")
    robot.add_argument("--video", action="store_true", help="also write OUT/<case>/replay.mp4 (needs -o)")
    robot.set_defaults(run=_bench_robot)
    real = bench.add_parser("something-else", help="the paper's success table on annotated real videos")
    real.add_argument("--annotations", type=Path, required=True, help="Something-Else boxes (JSON)")
    real.add_argument("--phases", type=Path, required=True, help="action phases (CSV)")
    real.add_argument("--actions", type=Path, required=True, help="video_id,action (CSV)")
    real.add_argument("-o", "--out", type=Path, default=Path("warpskill-out/something-else"), help="output folder")
    real.add_argument("--videos", nargs="*", help="a subset of the video ids (default: all)")
    real.add_argument("--device", default="cpu")
    real.add_argument("--iterations", type=int, help="physics-stage iterations (default: the library's)")
    real.set_defaults(run=_bench_something_else)
    return parser


def _add_optimise_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--device", default=None, help="cpu (default) or cuda")
    parser.add_argument("--iterations", type=int, default=None, help="physics-stage iterations")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quiet", action="store_true", help="no progress bars")


def _add_placement_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--offset", type=float, nargs=2, default=(0.5, 0.0), metavar=("X", "Y"),
                        help="scene centre in the robot base frame [m] (default: 0.5 0.0)")
    parser.add_argument("--yaw", type=float, default=90.0,
                        help="direction of the robot's forward axis in the world, about z [deg] (default: 90)")


def _placement(args):
    from warpskill.robot.model import Placement

    return Placement(offset=tuple(args.offset), yaw=math.radians(args.yaw))


def _reconstruct(demos, folders: list[Path], checkpoint: Path, args, *, init_only: bool = False,
                 pictures: bool = True):
    """Optimise ``demos`` together (resuming ``checkpoint``); write each npz and pictures into its folder."""
    from warpskill.engine.device import resolve_device
    from warpskill.optimizer.pipeline import optimize_many
    from warpskill.visual.pictures import save_pictures

    resolve_device(args.device)
    checkpoint.parent.mkdir(parents=True, exist_ok=True)
    reconstructions = optimize_many(
        demos,
        device=args.device,
        iterations=args.iterations,
        seed=args.seed,
        progress=not args.quiet,
        init_only=init_only,
        checkpoint=checkpoint,
    )
    for demo, recon, out in zip(demos, reconstructions, folders):
        out.mkdir(parents=True, exist_ok=True)
        recon.save(out / "reconstruction.npz")
        print(f"reconstruction: {out / 'reconstruction.npz'}")
        if pictures:
            for name, path in save_pictures(recon, demo, out).items():
                print(f"{name}: {path}")
        _report(recon, demo.action)
    return reconstructions


def _report(recon, action) -> None:
    from warpskill.contract.evaluation import evaluate

    if action:
        result = evaluate(recon, action)
        failed = [name for name, ok in result.checks.items() if not ok]
        verdict = "success" if result.success else "failure (" + ", ".join(failed) + ")"
        print(f"{action}: {verdict}")


def _demo(args) -> int:
    from warpskill.robot.video import prefer_headless_gl
    from warpskill.synthetic import make_demonstration

    prefer_headless_gl()
    demo = make_demonstration(args.action, seed=args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    demo.save(args.out / "demonstration.npz")
    print(f"demonstration: {args.out / 'demonstration.npz'} ({args.action}, {demo.num_frames} frames)")
    [recon] = _reconstruct([demo], [args.out], args.out / "checkpoint.pt", args)
    if args.no_robot:
        return 0
    missing = [name for name in ("placo", "mujoco", "example-robot-data") if not _installed(name)]
    if missing:
        print(f"robot steps skipped ({', '.join(missing)} not installed): pip install 'warpskill[robot]'")
        return 0
    from warpskill.robot.plan import PlanError
    from warpskill.robot.replaying import replay
    from warpskill.robot.retargeting import retarget
    from warpskill.robot.video import record

    try:
        plan = retarget(recon, placement=_placement(args))
    except PlanError as error:
        print(f"robot plan: none: {error}")
        return 0
    _save_plan(plan, args.out / "plan.npz")
    result = replay(plan, recon)
    result.save(args.out / "replay.npz")
    print(f"replay: {args.out / 'replay.npz'} (mujoco, {result.replay_time:.2f} s); "
          f"picture: {record(plan, recon, result, args.out)}")
    _report(result.reconstruction, args.action)
    return 0


def _installed(distribution: str) -> bool:
    try:
        importlib.metadata.distribution(distribution)
    except importlib.metadata.PackageNotFoundError:
        return False
    return True


def _optimize(args) -> int:
    from warpskill.contract.demonstration import Demonstration

    stems = [path.stem for path in args.demos]
    if len(set(stems)) < len(stems):
        raise ValueError("demonstration files must have different names: each gets OUT/<name>/")
    demos = [Demonstration.load(path) for path in args.demos]
    folders = [args.out] if len(demos) == 1 else [args.out / stem for stem in stems]
    _reconstruct(demos, folders, args.out / "checkpoint.pt", args, init_only=args.init_only,
                 pictures=not args.no_pictures)
    return 0


def _evaluate(args) -> int:
    from warpskill.contract.evaluation import evaluate
    from warpskill.contract.reconstruction import Reconstruction

    recon = Reconstruction.load(args.reconstruction)
    action = args.action or str(recon.action) or None
    if not action:
        raise ValueError("the reconstruction names no action: pass --action")
    result = evaluate(recon, action, mode=args.mode)
    for name, ok in result.checks.items():
        print(f"  {'ok  ' if ok else 'FAIL'} {name}")
    print(f"{action}: {'success' if result.success else 'failure'}")
    return 0 if result.success else 3


def _retarget(args) -> int:
    from warpskill.contract.reconstruction import Reconstruction
    from warpskill.robot.retargeting import retarget

    plan = retarget(Reconstruction.load(args.reconstruction), placement=_placement(args))
    _save_plan(plan, args.out)
    return 0


def _save_plan(plan, path: Path) -> None:
    """Write the plan's ``.npz`` and ``.csv`` and say so."""
    path.parent.mkdir(parents=True, exist_ok=True)
    plan.save(path)
    plan.save_csv(path.with_suffix(".csv"))
    print(f"plan: {path} ({plan.num_samples} samples, {plan.t[-1]:.2f} s, grasp {plan.grasp_name}; "
          f"planned in {plan.planning_time:.2f} s)")


def _replay(args) -> int:
    from warpskill.robot.video import prefer_headless_gl

    prefer_headless_gl()
    from warpskill.contract.reconstruction import Reconstruction
    from warpskill.robot.plan import RobotPlan
    from warpskill.robot.replaying import replay
    from warpskill.robot.video import record

    recon = Reconstruction.load(args.reconstruction)
    plan = RobotPlan.load(args.plan)
    args.out.mkdir(parents=True, exist_ok=True)
    result = replay(plan, recon, engine=args.engine)
    result.save(args.out / "replay.npz")
    print(f"replay: {args.out / 'replay.npz'} ({args.engine}, {result.replay_time:.2f} s)")
    if args.video:
        print(f"video: {record(plan, recon, result, args.out)}")
    _report(result.reconstruction, result.evaluation.action)
    return 0 if result.success else 3


def _bench_kernels(args) -> int:
    from warpskill.bench.kernels import bench_kernels

    bench_kernels(device=args.device, repeats=args.repeats)
    return 0


def _bench_speed(args) -> int:
    from warpskill.bench.speed import bench_speed

    devices = ["cpu"] if args.device == "cpu" else ["cpu", args.device]
    bench_speed(devices=devices, engines=args.engines, repeats=args.repeats, measure_full=args.full,
                scaling=args.scaling, threads=args.threads)
    if args.many:
        from warpskill.bench.speed import bench_many

        bench_many(batches=args.many, devices=devices)
    return 0


def _bench_synthetic(args) -> int:
    from warpskill.bench.synthetic import bench_synthetic

    bench_synthetic(
        seeds=args.seeds, noise=args.noise, actions=args.actions, out=args.out, device=args.device,
        iterations=args.iterations,
    )
    return 0


def _bench_robot(args) -> int:
    from warpskill.bench.robot import bench_robot

    if args.video and args.out is None:
        raise ValueError("--video needs an output folder: -o OUT")
    bench_robot(seeds=args.seeds, source=args.source, engines=args.engines, actions=args.actions, out=args.out,
                device=args.device, video=args.video)
    return 0


def _bench_something_else(args) -> int:
    from warpskill.bench.something_else import bench_something_else

    bench_something_else(
        args.annotations, args.phases, args.actions, out=args.out, iterations=args.iterations,
        device=args.device, videos=args.videos,
    )
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
