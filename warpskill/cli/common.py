"""Helpers the command modules share: option groups, the reconstruction step, reports."""

from __future__ import annotations

import argparse
import importlib.metadata
import math
from pathlib import Path

__all__ = ["add_optimise_options", "add_placement_options", "installed", "placement", "robot_steps_available", "reconstruct", "report", "save_plan",
           "save_scene"]


def add_optimise_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--device", default=None, help="cpu (default) or cuda")
    parser.add_argument("--iterations", type=int, default=None, help="physics-stage iterations")
    parser.add_argument("--seed", type=int, default=0, help="Torch seed (results are deterministic per seed and device)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.add_argument("--known", nargs="+", default=None, metavar="NAME=METRES",
                        help="lengths known in advance, which fix the scene's scale, e.g. object_height=0.10 "
                             "(also object_width, object_depth, camera_height, static_height, static_width, "
                             "static_depth)")


def add_placement_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--offset", type=float, nargs=2, default=None, metavar=("X", "Y"),
                        help="fix the scene centre in the robot base frame [m] (default: searched; 0.5 0.0 "
                             "with --yaw alone)")
    parser.add_argument("--yaw", type=float, default=None,
                        help="fix the direction of the robot's forward axis in the world, about z [deg] "
                             "(default: searched; 90 with --offset alone)")


def placement(args):
    """``"auto"`` (the robot's base pose is searched) unless ``--offset`` or ``--yaw`` fix it."""
    from warpskill.robot import Placement

    if args.offset is None and args.yaw is None:
        return "auto"
    default = Placement()
    offset = default.offset if args.offset is None else tuple(args.offset)
    yaw = default.yaw if args.yaw is None else math.radians(args.yaw)
    return Placement(offset=offset, yaw=yaw)


def reconstruct(demos, folders: list[Path], checkpoint: Path, args, *, init_only: bool = False,
                 pictures: bool = True):
    """Optimise ``demos`` together (resuming ``checkpoint``); write each npz and pictures into its folder."""
    from warpskill.engine import resolve_device
    from warpskill.optimizer import optimize_many, parse_known
    from warpskill.visual import save_pictures

    resolve_device(args.device)
    known = parse_known(getattr(args, "known", None))
    checkpoint.parent.mkdir(parents=True, exist_ok=True)
    reconstructions = optimize_many(
        demos,
        device=args.device,
        iterations=args.iterations,
        seed=args.seed,
        progress=not args.quiet,
        init_only=init_only,
        checkpoint=checkpoint,
        known=known,
    )
    for demo, recon, out in zip(demos, reconstructions, folders):
        out.mkdir(parents=True, exist_ok=True)
        recon.save(out / "reconstruction.npz")
        print(f"reconstruction: {out / 'reconstruction.npz'}")
        if pictures:
            for name, path in save_pictures(recon, demo, out).items():
                print(f"{name}: {path}")
            save_scene(recon, demo, out)
        report(recon, demo.action)
    return reconstructions


def report(recon, action) -> None:
    from warpskill.contract import evaluate

    if action:
        result = evaluate(recon, action)
        failed = [name for name, ok in result.checks.items() if not ok]
        verdict = "success" if result.success else "failure (" + ", ".join(failed) + ")"
        print(f"{action}: {verdict}")


def save_plan(plan, path: Path) -> None:
    """Write the plan's ``.npz`` and ``.csv`` and say so."""
    path.parent.mkdir(parents=True, exist_ok=True)
    plan.save(path)
    plan.save_csv(path.with_suffix(".csv"))
    print(f"plan: {path} ({plan.num_samples} samples, {plan.t[-1]:.2f} s, grasp {plan.grasp_name}; "
          f"planned in {plan.planning_time:.2f} s)")
    if plan.offset is not None:
        print(f"placement ({plan.placement}): scene centre at ({plan.offset[0]:.2f}, {plan.offset[1]:.2f}) m "
              f"in the base frame, yaw {math.degrees(plan.yaw):.0f} deg")
    if plan.note:
        print(plan.note)


def save_scene(recon, demo, out: Path, plan=None, replay=None, *, quiet: bool = False) -> None:
    """Write ``out/scene.rrd`` (the 3D Rerun recording) and say so; without rerun-sdk, say how to get it."""
    from warpskill.visual import view

    try:
        path = view(recon, demo, plan, replay, path=out / "scene.rrd")
    except ModuleNotFoundError as error:
        if error.name != "rerun":
            raise
        if not quiet:
            print('scene: none (the 3D recording needs rerun-sdk: pip install -e ".[viewer]")')
        return
    if not quiet:
        print(f"scene: {path} (open with: rerun {path})")


ROBOT_PACKAGES = ("placo", "mujoco", "example-robot-data")
"""The distributions the robot steps (retarget, replay) need: the ``robot`` extra."""


def robot_steps_available() -> bool:
    """Whether :data:`ROBOT_PACKAGES` are installed; if not, say in one line how to get them."""
    missing = [name for name in ROBOT_PACKAGES if not installed(name)]
    if missing:
        print(f"robot steps skipped ({', '.join(missing)} not installed): pip install 'warpskill[robot]'")
    return not missing


def installed(distribution: str) -> bool:
    """Whether the Python distribution ``distribution`` is installed."""
    try:
        importlib.metadata.distribution(distribution)
    except importlib.metadata.PackageNotFoundError:
        return False
    return True
