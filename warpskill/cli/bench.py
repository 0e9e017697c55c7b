"""``warpskill bench ...``: kernel microbenchmarks, iteration speed, and the success tables."""

from __future__ import annotations

from pathlib import Path

from warpskill.cli.common import add_optimize_options, optimize_options
from warpskill.contract import Reconstruction

__all__ = ["register"]


def register(commands) -> None:
    """Add ``bench`` and its benchmarks to the ``commands`` sub-parsers."""
    bench = commands.add_parser("bench", help="benchmarks").add_subparsers(title="benchmarks")
    for add in (_add_kernels, _add_speed, _add_synthetic, _add_robot, _add_generalize, _add_something_else,
                _add_second_opinion, _add_footage, _add_flips):
        add(bench)


def _add_kernels(bench) -> None:
    """``warpskill bench kernels``."""
    kernels = bench.add_parser("kernels", help="Warp kernel microbenchmarks")
    kernels.add_argument("--device", default="cpu", help="cpu or cuda")
    kernels.add_argument("--repeats", type=int, default=5, help="timed repetitions (median reported)")
    kernels.set_defaults(run=_bench_kernels)


def _add_speed(bench) -> None:
    """``warpskill bench speed``."""
    speed = bench.add_parser("speed", help="optimisation iterations: Warp engine vs its plain-Torch reference")
    speed.add_argument("--device", default="cpu", help="cpu, or cuda (then the CPU too)")
    speed.add_argument("--engines", nargs="+", default=["warp", "reference"], help="warp and/or reference")
    speed.add_argument("--repeats", type=int, default=3,
                       help="timed iterations (median reported); with --clip: runs per checkout (least reported)")
    speed.add_argument("--full", action="store_true", help="also time warpskill.optimize end to end per engine")
    speed.add_argument("--scaling", action="store_true", help="also time iterations as frames, image size, B grow")
    speed.add_argument("--many", type=int, nargs="+", metavar="B",
                       help="also run warpskill.optimize_many on B synthetic demonstrations: demonstrations per second")
    speed.add_argument("--set", choices=("dev", "synthetic"), dest="speed_set",
                       help="instead: time warpskill.optimize per stage over a set, one case after another")
    speed.add_argument("--against", metavar="CHECKOUT",
                       help="with --set or --clip: also time this checkout (a git worktree of the previous commit), "
                            "interleaved")
    speed.add_argument("--baseline", metavar="FILE", help="with --set: the previous figures from a JSON file of -o")
    speed.add_argument("-o", "--out", metavar="FILE",
                       help="with --set: write this run's figures (JSON); with --clip: the folder of the clip, its "
                            "runs and clip_speed.json (default warpskill-out/clip-speed)")
    speed.add_argument("--seeds", type=int, default=1, help="with --set synthetic: seeds per action (default: 1)")
    speed.add_argument("--folder", type=Path, help="with --set dev: the development videos' folder "
                       "(annotations.json, phases.csv, actions.csv; default: $WARPSKILL_DEV_DATA)")
    speed.add_argument("--videos", nargs="+", default=(), help="with --set dev: a subset of the video ids")
    speed.add_argument("--clip", action="store_true",
                       help="instead: time warpskill run per step on a rendered 640 x 480, 30 fps put_onto clip "
                            "(--repeats runs, -o DIR, --cores, --against)")
    speed.add_argument("--cores", default="0", help="with --clip: the cores each run is pinned to (taskset -c; "
                       "default 0; 'none': unpinned)")
    speed.set_defaults(run=_bench_speed)


def _add_synthetic(bench) -> None:
    """``warpskill bench synthetic``."""
    synthetic = bench.add_parser("synthetic", help="the 9 actions x N seeds: the paper's success table")
    synthetic.add_argument("--seeds", type=int, default=3, help="seeds per action (default: 3)")
    synthetic.add_argument("--noise", default="moderate", help="none, low, moderate or high")
    synthetic.add_argument("--actions", nargs="*", help="a subset of the actions (default: all 9)")
    synthetic.add_argument("-o", "--out", type=Path, help="also write every demonstration and reconstruction here")
    synthetic.add_argument("--input", choices=("masks", "boxes"), default="masks",
                           help="true silhouettes with mask noise, or ellipses in their boxes as for Something-Else")
    synthetic.add_argument("--seed-start", type=int, default=0, help="first seed")
    synthetic.add_argument("--scenarios", choices=("none", "real", "narrow", "turned", "flat", "askew", "relations"),
                           default="none",
                           help="with --input boxes: also the held-out real videos' situations (real, mixed in by "
                                "seed), static boxes narrower than the object (narrow, put actions), static "
                                "boxes turned by up to 30 deg (turned, put actions), long thin objects lying "
                                "flat (flat), or lying flat at up to 69 deg (askew, pushes and pulls at 0), or "
                                "named objects and statics at their nouns' sizes filmed low over a table "
                                "(relations: pick up and the put actions, the default actions then)")
    synthetic.add_argument("--nouns", action="store_true",
                           help="give each object a noun whose typical size is its own times a log-normal spread")
    add_optimize_options(synthetic, known_names=True)
    _add_baseline_options(synthetic)
    synthetic.set_defaults(run=_bench_synthetic)


def _add_robot(bench) -> None:
    """``warpskill bench robot``."""
    robot = bench.add_parser("robot", help="retarget synthetic reconstructions to the Panda and replay them")
    robot.add_argument("--seeds", type=int, default=3, help="seeds per action (default: 3)")
    robot.add_argument("--source", choices=("truth", "optimised"), default="truth",
                       help="ground-truth reconstructions, or the optimiser's output on noisy demonstrations")
    robot.add_argument("--engines", nargs="+", choices=("mujoco", "newton"), default=["mujoco"],
                       help="replay engines (default: mujoco)")
    robot.add_argument("--actions", nargs="*", help="a subset of the actions (default: all 9)")
    robot.add_argument("-o", "--out", type=Path, help="keep reconstructions and plans here (reused on a rerun)")
    robot.add_argument("--video", action="store_true", help="also write OUT/<case>/replay.mp4 (needs -o)")
    robot.add_argument("--no-robust", dest="robust", action="store_false",
                       help="skip the perturbed replays (the robust row)")
    add_optimize_options(robot)  # for --source optimised; --device is also Newton's
    robot.set_defaults(run=_bench_robot)


def _add_generalize(bench) -> None:
    """``warpskill bench generalize``."""
    generalize = bench.add_parser("generalize", help="each skill in random layouts: planned, succeeded, robust")
    generalize.add_argument("reconstructions", type=Path, nargs="+", help="reconstruction .npz files")
    generalize.add_argument("--layouts", type=int, default=10, help="random layouts per skill (default: 10)")
    generalize.add_argument("--engines", nargs="+", choices=("mujoco", "newton"), default=["mujoco"],
                            help="replay engines (default: mujoco)")
    generalize.add_argument("--seed", type=int, default=0, help="seed of the layouts")
    generalize.add_argument("--device", default="cpu", help="Warp device of Newton")
    generalize.add_argument("--no-robust", dest="robust", action="store_false",
                            help="skip the perturbed replays (the robust row)")
    generalize.add_argument("-o", "--out", type=Path, help="write the per-layout outcome table into this folder")
    _add_baseline_options(generalize)
    generalize.set_defaults(run=_bench_generalize)


def _add_something_else(bench) -> None:
    """``warpskill bench something-else``."""
    real = bench.add_parser("something-else", help="the paper's success table on annotated real videos")
    real.add_argument("--annotations", type=Path, required=True, help="Something-Else boxes (JSON)")
    real.add_argument("--phases", type=Path, required=True, help="action phases (CSV)")
    real.add_argument("--actions", type=Path, required=True, help="video_id,action (CSV)")
    real.add_argument("-o", "--out", type=Path, default=Path("warpskill-out/something-else"), help="output folder")
    real.add_argument("--videos", nargs="*", help="a subset of the video ids (default: all)")
    real.add_argument("--workers", type=int, metavar="N",
                      help="reconstruct on N Ray workers at a time (one per core; needs the cluster extra)")
    real.add_argument("--ray-address", metavar="ADDR", help="join this Ray cluster (default: $RAY_ADDRESS)")
    real.add_argument("--robot", action="store_true",
                      help="also plan each reconstruction for the Panda and replay it (the end-to-end table)")
    real.add_argument("--engines", nargs="+", choices=("mujoco", "newton"), default=["mujoco", "newton"],
                      help="replay engines of --robot")
    real.add_argument("--video", action="store_true", help="with --robot, also write OUT/<video>/replay.mp4")
    real.add_argument("--jitter", type=float, default=0.0, metavar="PX",
                      help="move every box corner by up to PX pixels in x and y (uniform, seeded) before reading; "
                           "with --baseline, the verdicts that flip")
    real.add_argument("--jitter-seed", type=int, default=0, metavar="S", help="seed of --jitter's draws (default 0)")
    add_optimize_options(real)
    _add_baseline_options(real)
    real.set_defaults(run=_bench_something_else)


def _add_second_opinion(bench) -> None:
    """``warpskill bench second-opinion``."""
    second = bench.add_parser("second-opinion",
                              help="an independent generator's scenes through the Something-Else reader")
    second.add_argument("-o", "--out", type=Path, default=Path("warpskill-out/second-opinion"), help="output folder")
    second.add_argument("--seeds", type=_seed_range, default=range(1, 11), help="seeds, e.g. 1..10 (default)")
    second.add_argument("--actions", nargs="*", help="a subset of the actions (default: all 9)")
    second.add_argument("--exit-view", action="store_true", help="pick-ups lifted out of the top of the view")
    second.add_argument("--noise", type=int, choices=(0, 1, 2), default=0, help="the generator's noise level")
    second.add_argument("--tools", type=Path, help="folder of synthdemo.py and synth_sthelse.py "
                        "(default: $WARPSKILL_TOOLS)")
    add_optimize_options(second)
    _add_baseline_options(second)
    second.set_defaults(run=_bench_second_opinion)


def _add_footage(bench) -> None:
    """``warpskill bench footage``."""
    footage = bench.add_parser("footage", help="real clips outlined on one frame, the hand found: masks against "
                                                "people's boxes (extra video)")
    footage.add_argument("folder", type=Path, help="a folder in the real-footage format (frames/<id>/, annotations.json)")
    footage.add_argument("--clips", nargs="*", help="a subset of the clip ids (default: all)")
    footage.add_argument("-o", "--out", type=Path, default=Path("warpskill-out/footage"),
                         help="output folder of outcomes.json / .csv")
    footage.add_argument("--quiet", action="store_true", help="no progress bar")
    footage.add_argument("--no-outline", action="store_true",
                         help="nobody outlines: the outline proposed from each clip (put_onto where a static object is "
                              "boxed, else pick_up; the boxed noun); a refused clip counts 0 (pictures in OUT/proposals/)")
    _add_baseline_options(footage)
    footage.set_defaults(run=_bench_footage)


def _add_flips(bench) -> None:
    """``warpskill bench flips``."""
    flips = bench.add_parser("flips", help="the cases that flipped between two outcome tables or output folders")
    flips.add_argument("baseline", type=Path, help="outcomes.json, or a benchmark's output folder")
    flips.add_argument("current", type=Path, help="outcomes.json, or a benchmark's output folder")
    flips.set_defaults(run=_bench_flips)


def _add_baseline_options(parser) -> None:
    """``--baseline`` and ``--save-baseline`` of the success benchmarks."""
    parser.add_argument("--baseline", type=Path, metavar="FILE",
                        help="print every case that flipped since this outcome table or output folder")
    parser.add_argument("--save-baseline", type=Path, metavar="FILE", help="also save this run's outcome table here")


def _seed_range(text: str) -> range:
    """'1..10' -> range(1, 11); '7' -> range(7, 8)."""
    first, _, last = text.partition("..")
    try:
        return range(int(first), int(last or first) + 1)
    except ValueError:
        raise ValueError(f"--seeds: expected FIRST..LAST or one seed, got {text!r}") from None


def _bench_kernels(args) -> int:
    from warpskill.bench.kernels import bench_kernels  # torch and Warp: only for this command

    bench_kernels(device=args.device, repeats=args.repeats)
    return 0


def _bench_speed(args) -> int:
    from warpskill.bench.speed import bench_many, bench_speed, bench_speed_set  # torch and Warp: only here

    if args.clip:
        from warpskill.bench.clip_speed import bench_clip_speed  # torch and Warp: only here

        if args.speed_set:
            raise ValueError("--clip and --set are two benchmarks: give one")
        bench_clip_speed(args.out or "warpskill-out/clip-speed", repeats=args.repeats, against=args.against,
                         cores=None if args.cores == "none" else args.cores)
        return 0
    if args.speed_set:
        bench_speed_set(args.speed_set, against=args.against, baseline=args.baseline, out=args.out,
                        folder=args.folder, seeds=args.seeds, videos=args.videos)
        return 0
    devices = ["cpu"] if args.device == "cpu" else ["cpu", args.device]
    bench_speed(devices=devices, engines=args.engines, repeats=args.repeats, measure_full=args.full,
                scaling=args.scaling)
    if args.many:
        bench_many(batches=args.many, devices=devices)
    return 0


def _bench_synthetic(args) -> int:
    from warpskill.bench.synthetic import bench_synthetic  # torch and Warp: only for this command

    options = optimize_options(args, cannot=dict(
        seed="each case is optimised with its own seed (--seeds, --seed-start)",
        init_only="the table already has the initialisation-only row"))
    actions = args.actions
    if actions is None and args.scenarios == "relations":
        from warpskill.synthetic import RELATION_ACTIONS
        actions = list(RELATION_ACTIONS)
    bench_synthetic(options, seeds=args.seeds, noise=args.noise, actions=actions, out=args.out, input=args.input,
                    known=args.known_names, seed_start=args.seed_start, scenarios=args.scenarios,
                    baseline=args.baseline, save_baseline=args.save_baseline, nouns=args.nouns)
    return 0


def _bench_robot(args) -> int:
    from warpskill.bench.robot import bench_robot  # torch and Warp: only for this command

    if args.video and args.out is None:
        raise ValueError("--video needs an output folder: -o OUT")
    cannot = dict(seed="each case is optimised with its own seed (--seeds)",
                  init_only="the robot is planned on the full method's reconstructions")
    if args.source == "truth":
        cannot.update({name: "--source truth optimises nothing" for name in ("iterations", "known", "settings")})
    options = optimize_options(args, cannot=cannot)
    bench_robot(options, seeds=args.seeds, source=args.source, engines=args.engines, actions=args.actions,
                out=args.out, video=args.video, robust=args.robust)
    return 0


def _bench_generalize(args) -> int:
    from warpskill.bench.generalize import bench_generalize  # the robot layer (matplotlib, PyAV): only for this command

    recons = {str(path): Reconstruction.load(path) for path in args.reconstructions}
    bench_generalize(recons, layouts=args.layouts, engines=args.engines, seed=args.seed, device=args.device,
                     robust=args.robust, out=args.out, baseline=args.baseline, save_baseline=args.save_baseline)
    return 0


def _bench_something_else(args) -> int:
    from warpskill.bench.something_else import bench_something_else  # torch and Warp: only for this command

    if args.video and not args.robot:
        raise ValueError("--video needs --robot")
    bench_something_else(
        args.annotations, args.phases, args.actions, optimize_options(args), out=args.out, videos=args.videos,
        workers=args.workers, address=args.ray_address, robot=args.robot, engines=args.engines, video=args.video,
        baseline=args.baseline, save_baseline=args.save_baseline, jitter=args.jitter, jitter_seed=args.jitter_seed,
    )
    return 0


def _bench_second_opinion(args) -> int:
    from warpskill.bench.second_opinion import bench_second_opinion  # torch and Warp: only for this command

    result = bench_second_opinion(args.out, optimize_options(args), seeds=args.seeds, actions=args.actions,
                                  exit_view=args.exit_view, noise=args.noise, tools=args.tools,
                                  baseline=args.baseline, save_baseline=args.save_baseline)
    return 0 if result is not None else 1


def _bench_footage(args) -> int:
    from warpskill.bench.footage import bench_footage

    scores = bench_footage(args.folder, args.out, clips=args.clips, baseline=args.baseline,
                           save_baseline=args.save_baseline, quiet=args.quiet, no_outline=args.no_outline)
    return 0 if scores else 2


def _bench_flips(args) -> int:
    from warpskill.bench.outcomes import flip_report, load_outcomes  # torch: only for this command

    print(flip_report(load_outcomes(args.baseline), load_outcomes(args.current), name=str(args.baseline)))
    return 0
