"""``warpskill bench ...``: kernel microbenchmarks, iteration speed, and the success tables."""

from __future__ import annotations

from pathlib import Path

__all__ = ["register"]


def register(commands) -> None:
    """Add ``bench`` and its benchmarks to the ``commands`` sub-parsers."""
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
    synthetic.add_argument("--seeds", type=int, default=3, help="seeds per action (default: 3)")
    synthetic.add_argument("--noise", default="moderate", help="none, low, moderate or high")
    synthetic.add_argument("--actions", nargs="*", help="a subset of the actions (default: all 9)")
    synthetic.add_argument("-o", "--out", type=Path, help="also write every demonstration and reconstruction here")
    synthetic.add_argument("--device", default="cpu", help="cpu or cuda")
    synthetic.add_argument("--iterations", type=int, help="physics-stage iterations (default: the library's)")
    synthetic.add_argument("--input", choices=("masks", "boxes"), default="masks",
                           help="true silhouettes with mask noise, or ellipses in their boxes as for Something-Else")
    synthetic.add_argument("--known", nargs="*", default=[], metavar="NAME",
                           help="lengths given to the optimiser at their true values, e.g. object_height")
    synthetic.add_argument("--seed-start", type=int, default=0, help="first seed")
    synthetic.set_defaults(run=_bench_synthetic)
    robot = bench.add_parser("robot", help="retarget synthetic reconstructions to the Panda and replay them")
    robot.add_argument("--seeds", type=int, default=3, help="seeds per action (default: 3)")
    robot.add_argument("--source", choices=("truth", "optimised"), default="truth",
                       help="ground-truth reconstructions, or the optimiser's output on noisy demonstrations")
    robot.add_argument("--engines", nargs="+", choices=("mujoco", "newton"), default=["mujoco"],
                       help="replay engines (default: mujoco)")
    robot.add_argument("--actions", nargs="*", help="a subset of the actions (default: all 9)")
    robot.add_argument("-o", "--out", type=Path, help="keep reconstructions and plans here (reused on a rerun)")
    robot.add_argument("--device", default="cpu", help="cpu or cuda (for --source optimised)")
    robot.add_argument("--video", action="store_true", help="also write OUT/<case>/replay.mp4 (needs -o)")
    robot.set_defaults(run=_bench_robot)
    real = bench.add_parser("something-else", help="the paper's success table on annotated real videos")
    real.add_argument("--annotations", type=Path, required=True, help="Something-Else boxes (JSON)")
    real.add_argument("--phases", type=Path, required=True, help="action phases (CSV)")
    real.add_argument("--actions", type=Path, required=True, help="video_id,action (CSV)")
    real.add_argument("-o", "--out", type=Path, default=Path("warpskill-out/something-else"), help="output folder")
    real.add_argument("--videos", nargs="*", help="a subset of the video ids (default: all)")
    real.add_argument("--device", default="cpu", help="cpu or cuda")
    real.add_argument("--iterations", type=int, help="physics-stage iterations (default: the library's)")
    real.add_argument("--workers", type=int, metavar="N",
                      help="reconstruct on N Ray workers at a time (one per core; needs the cluster extra)")
    real.add_argument("--ray-address", metavar="ADDR", help="join this Ray cluster (default: $RAY_ADDRESS)")
    real.add_argument("--robot", action="store_true",
                      help="also plan each reconstruction for the Panda and replay it (the end-to-end table)")
    real.add_argument("--engines", nargs="+", choices=("mujoco", "newton"), default=["mujoco", "newton"],
                      help="replay engines of --robot")
    real.add_argument("--video", action="store_true", help="with --robot, also write OUT/<video>/replay.mp4")
    real.set_defaults(run=_bench_something_else)


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
        iterations=args.iterations, input=args.input, known=args.known, seed_start=args.seed_start,
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

    if args.video and not args.robot:
        raise ValueError("--video needs --robot")
    bench_something_else(
        args.annotations, args.phases, args.actions, out=args.out, iterations=args.iterations,
        device=args.device, videos=args.videos, workers=args.workers, address=args.ray_address,
        robot=args.robot, engines=args.engines, video=args.video,
    )
    return 0
