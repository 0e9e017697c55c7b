"""``warpskill run``: one's own video to a replayed robot skill, in one resumable command.

The steps and what each writes under OUT/:

    prepare    demonstration.npz, demo.png (the contact sheet); without a mask source also
               outline.json, the outline proposed from the video (docs/formats.md), to correct and
               give back with --polygons (unsure: only demonstration.unsure.png, what was seen)
    optimize   reconstruction.npz, overlay.gif, top_view.png, trajectories.png (checkpoint.pt meanwhile)
    retarget   plan.npz, plan.csv
    replay     replay.npz
    (then)     scene.rrd, the 3D Rerun recording of all of it (with rerun-sdk)
    (at last)  timing.json, the seconds each step took (also printed)

A video well above the optimiser's 12 fps (a phone's 30 fps) is optimised on every few of its
frames (:func:`warpskill.contract.frame_rate.at_optimiser_rate`): the reconstruction, its
pictures and the robot's timing are at that rate, on the video's clock.

A step is finished when its output file exists and loads (and, for the reconstruction, was
made with the options asked now, its ``options`` of docs/formats.md, the device aside); a
rerun skips finished steps and redoes every step after one it had to redo. Exit status: 0 when the replay succeeds (or
the robot steps are skipped, placo / MuJoCo missing), 3 when a step stopped the run (no
robot plan) or the replay fails the action's criteria, 2 when the recording gives no
demonstration (no hand found, an object lost, an outline outside the frame, ...), 1 for
other bad input (a missing file).
"""

from __future__ import annotations

from pathlib import Path

from warpskill import robot, visual  # lazy packages: their names (MuJoCo, torch, Warp) load on first use
from warpskill.cli import common
from warpskill.cli.prepare import add_recording_options, prepare
from warpskill.contract import ResultsFolder, at_optimiser_rate, frame_stride
from warpskill.data import read_video

__all__ = ["register"]


def register(commands) -> None:
    """Add ``run`` to the ``commands`` sub-parsers."""
    parser = commands.add_parser("run", help="prepare + optimize + retarget + replay one's own video (resumable)")
    add_recording_options(parser)
    parser.add_argument("-o", "--out", type=Path, required=True, help="output folder")
    parser.add_argument("--engine", choices=("mujoco", "newton"), default="mujoco", help="replay engine")
    common.add_optimize_options(parser)
    common.add_robot_step_options(parser)
    parser.set_defaults(run=_run)


@common.holding_out
def _run(args) -> int:
    clock = common.StepClock()
    status = _steps(args, clock)
    clock.report(ResultsFolder(args.out).timing)
    return status


def _steps(args, clock: common.StepClock) -> int:
    options = common.optimize_options(args)
    out = args.out
    keeper = ResultsFolder(out)
    demo_path, sheet_path = keeper.demonstration, out / "demo.png"
    redo = False
    demo = keeper.finished_demonstration() if sheet_path.is_file() else None
    frames = None
    if demo is None:
        redo = True
        with clock.step("prepare"):
            demo, frames = prepare(args, demo_path, sheet_path, out / "outline.json")
    else:
        print(f"prepare: done, skipped ({demo_path}, {sheet_path})")
    stride = frame_stride(demo.fps)
    demo, frames = at_optimiser_rate(demo), None if frames is None else frames[::stride]

    recon_path = keeper.reconstruction
    recon = None if redo else keeper.finished_reconstruction(options.to_json())
    if recon is not None and recon.num_frames != demo.num_frames:  # made before the video was thinned: redone
        recon = None
    if recon is None:
        redo = True
        if frames is None:
            frames = _frames(args.video, demo, stride)
        with clock.step("optimize"):
            [recon] = common.reconstruct([demo], [out], keeper.checkpoint, options, quiet=args.quiet, pictures=False)
        with clock.step("pictures"):
            for name, path in visual.save_pictures(recon, demo, out, background=frames).items():
                print(f"{name}: {path}")
    else:
        print(f"optimize: done, skipped ({recon_path})")
        common.report(recon, demo.action)

    if not common.robot_steps_wanted(args):
        _scene(recon, demo, args.video, stride, frames, out, redo, clock)
        return 0
    robot.prefer_headless_gl()

    plan_path = keeper.plan
    plan = None if redo or not keeper.plan_csv.is_file() else keeper.load_finished(plan_path, robot.RobotPlan.load)
    if plan is None:
        redo = True
        with clock.step("retarget"):
            plan = common.plan_robot(recon, args)
        if plan is None:
            _scene(recon, demo, args.video, stride, frames, out, redo, clock)
            return 3
        common.save_plan(plan, plan_path)
    else:
        print(f"retarget: done, skipped ({plan_path})")

    replay_path = keeper.replay
    result = None if redo else keeper.finished_replay()
    if result is None:
        redo = True
        with clock.step("replay"):
            result = robot.replay(plan, recon, engine=args.engine)
        keeper.save(result, replay_path)
        print(f"replay: {replay_path} ({args.engine}, {result.replay_time:.2f} s)")
    else:
        print(f"replay: done, skipped ({replay_path})")
    common.report(result.reconstruction, demo.action)
    _scene(recon, demo, args.video, stride, frames, out, redo, clock, plan, result)
    return 0 if result.success else 3


def _scene(recon, demo, video: Path, stride: int, frames, out: Path, redo: bool, clock: common.StepClock,
           plan=None, result=None) -> None:
    """The 3D recording (``scene.rrd``) of what exists, the video's fitted frames included (``frames``,
    or read again when None), unless nothing changed since it was written."""
    if redo or not (out / "scene.rrd").is_file():
        with clock.step("scene"):
            frames = _frames(video, demo, stride) if frames is None else frames
            common.save_scene(recon, demo, out, plan, result, frames=frames)


def _frames(video: Path, demo, stride: int):
    """The video's frames the optimiser fitted (every ``stride``-th) to draw the pictures on, or None
    when they are gone or do not fit ``demo``."""
    try:
        frames, _ = read_video(video)
    except (ValueError, OSError):
        return None
    frames = frames[::stride]
    return frames if frames.shape[:3] == (demo.num_frames, *demo.image_size) else None
