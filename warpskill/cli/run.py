"""``warpskill run``: one's own video to a replayed robot skill, in one resumable command.

The steps and what each writes under OUT/:

    prepare    demonstration.npz, demo.png (the contact sheet)
    optimize   reconstruction.npz, overlay.gif, top_view.png, trajectories.png (checkpoint.pt meanwhile)
    retarget   plan.npz, plan.csv
    replay     replay.npz
    (then)     scene.rrd, the 3D Rerun recording of all of it (with rerun-sdk)

A step is finished when its output file exists and loads; a rerun skips finished steps and
redoes every step after one it had to redo. Exit status: 0 when the replay succeeds (or
the robot steps are skipped, placo / MuJoCo missing), 3 when a step stopped the run (no
robot plan) or the replay fails the action's criteria, 1 for bad input.
"""

from __future__ import annotations

from pathlib import Path

from warpskill.cli.common import (
    add_optimise_options,
    add_placement_options,
    placement,
    reconstruct,
    report,
    robot_steps_available,
    save_plan,
    save_scene,
)
from warpskill.cli.prepare import add_recording_options, prepare

__all__ = ["register"]



def register(commands) -> None:
    """Add ``run`` to the ``commands`` sub-parsers."""
    parser = commands.add_parser("run", help="prepare + optimize + retarget + replay one's own video (resumable)")
    add_recording_options(parser)
    parser.add_argument("-o", "--out", type=Path, required=True, help="output folder")
    parser.add_argument("--engine", choices=("mujoco", "newton"), default="mujoco", help="replay engine")
    parser.add_argument("--no-robot", action="store_true", help="stop after the reconstruction")
    add_optimise_options(parser)
    add_placement_options(parser)
    parser.set_defaults(run=_run)


def _run(args) -> int:
    from warpskill.contract import Demonstration, Reconstruction
    from warpskill.visual import save_pictures

    out = args.out
    demo_path, sheet_path = out / "demonstration.npz", out / "demo.png"
    redo = False
    demo = _loaded(Demonstration.load, demo_path) if sheet_path.is_file() else None
    frames = None
    if demo is None:
        redo = True
        demo, frames = prepare(args, demo_path, sheet_path)
    else:
        print(f"prepare: done, skipped ({demo_path}, {sheet_path})")

    recon_path = out / "reconstruction.npz"
    recon = None if redo else _loaded(Reconstruction.load, recon_path)
    if recon is None:
        redo = True
        if frames is None:
            frames = _frames(args.video, demo)
        [recon] = reconstruct([demo], [out], out / "checkpoint.pt", args, pictures=False)
        for name, path in save_pictures(recon, demo, out, background=frames).items():
            print(f"{name}: {path}")
    else:
        print(f"optimize: done, skipped ({recon_path})")
        report(recon, demo.action)

    if args.no_robot:
        _scene(recon, demo, out, redo)
        return 0
    if not robot_steps_available():
        _scene(recon, demo, out, redo)
        return 0
    from warpskill.robot import (
        PlanError,
        RobotPlan,
        prefer_headless_gl,
        replay,
        retarget,
    )

    prefer_headless_gl()
    from warpskill import Replay

    plan_path = out / "plan.npz"
    plan = None if redo or not plan_path.with_suffix(".csv").is_file() else _loaded(RobotPlan.load, plan_path)
    if plan is None:
        redo = True
        try:
            plan = retarget(recon, placement=placement(args))
        except PlanError as error:
            print(f"retarget: stopped, no robot plan: {error}")
            _scene(recon, demo, out, redo)
            return 3
        save_plan(plan, plan_path)
    else:
        print(f"retarget: done, skipped ({plan_path})")

    replay_path = out / "replay.npz"
    result = None if redo else _loaded(Replay.load, replay_path)
    if result is None:
        redo = True
        result = replay(plan, recon, engine=args.engine)
        result.save(replay_path)
        print(f"replay: {replay_path} ({args.engine}, {result.replay_time:.2f} s)")
    else:
        print(f"replay: done, skipped ({replay_path})")
    report(result.reconstruction, demo.action)
    _scene(recon, demo, out, redo, plan, result)
    return 0 if result.success else 3


def _scene(recon, demo, out: Path, redo: bool, plan=None, result=None) -> None:
    """The 3D recording (``scene.rrd``) of what exists, unless nothing changed since it was written."""
    if redo or not (out / "scene.rrd").is_file():
        save_scene(recon, demo, out, plan, result)


def _loaded(load, path: Path):
    """``load(path)``, or None when the file is missing or does not load (then the step is redone)."""
    if not path.is_file():
        return None
    try:
        return load(path)
    except (ValueError, OSError) as error:
        print(f"{path}: does not load ({error}); redoing the step")
        return None


def _frames(video: Path, demo):
    """The video's frames to draw the pictures on, or None when they are gone or do not fit."""
    from warpskill.data import read_video

    try:
        frames, _ = read_video(video)
    except (ValueError, OSError):
        return None
    return frames if frames.shape[:3] == (demo.num_frames, *demo.image_size) else None
