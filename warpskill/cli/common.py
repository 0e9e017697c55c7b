"""Helpers the command modules share: option groups, the reconstruction step, reports."""

from __future__ import annotations

import argparse
import contextlib
import functools
import importlib.metadata
import json
import math
import time
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from warpskill import robot, visual  # lazy packages: their names (MuJoCo, torch, Warp) load on first use
from warpskill.contract import ResultsFolder, at_optimiser_rate, evaluate

if TYPE_CHECKING:  # the optimiser pulls in torch and Warp: imported where used, so the command line starts fast
    from warpskill.optimizer import OptimizeOptions

__all__ = ["StepClock", "add_optimize_options", "add_placement_options", "add_robot_step_options", "installed", "optimize_options",
           "placement", "plan_robot", "robot_steps_available", "robot_steps_wanted", "reconstruct", "holding_out",
           "report", "save_plan", "save_scene"]

OPTIMIZE_FLAGS = {"device": "--device", "iterations": "--iterations", "seed": "--seed", "init_only": "--init-only",
                  "known": "--known", "object_noun": "--object-noun", "settings": "--set"}
"""The options of :func:`add_optimize_options`: ``args`` attribute -> flag."""


class Refused(Exception):
    """Input a command understood but cannot carry out (a recording that gives no
    demonstration: no hand found, an object lost, an outline outside the frame): the
    command line prints its one line and exits with status 2."""


def add_optimize_options(parser: argparse.ArgumentParser, *, known_names: bool = False) -> None:
    """The optimisation options every optimising command shares (one :class:`OptimizeOptions`,
    saved as the reconstruction's ``options``, docs/formats.md), and ``--quiet``.

    ``known_names``: ``--known`` takes names whose true values the command knows
    (``bench synthetic``), not NAME=METRES; they land in ``args.known_names``, not in the options.
    """
    group = parser.add_argument_group("optimisation (saved as the reconstruction's options, docs/formats.md)")
    group.add_argument("--device", default=None, help="cpu (default) or cuda")
    group.add_argument("--iterations", type=int, default=None, help="physics-stage iterations (config.iterations)")
    group.add_argument("--seed", type=int, default=None,
                       help="Torch seed, default 0 (on the CPU results repeat exactly per seed; on CUDA they vary slightly)")
    group.add_argument("--init-only", action="store_true", help="stop after the physics-free initialisation")
    names = "(also object_width, object_depth, camera_height, static_height, static_width, static_depth)"
    if known_names:
        group.add_argument("--known", dest="known_names", nargs="+", default=[], metavar="NAME",
                           help=f"lengths given to the optimiser at each scene's true values, e.g. object_height {names}")
        parser.set_defaults(known=None)
    else:
        group.add_argument("--known", nargs="+", default=None, metavar="NAME=METRES",
                           help=f"lengths known in advance, which fix the scene's scale, e.g. object_height=0.10 {names}")
    group.add_argument("--object-noun", default=None, metavar="NOUN",
                       help="what the manipulated object is (e.g. mug), instead of the demonstration's noun: "
                            "without a known length, its typical size is a weak prior on the object's size")
    group.add_argument("--set", dest="settings", action="append", default=[], metavar="PATH=VALUE",
                       help="any setting of the options by its dotted path, e.g. config.init_iterations=100 or "
                            "config.weights.grasp_margin=0.01 (repeatable)")
    group.add_argument("--quiet", action="store_true", help="no progress bars")


def optimize_options(args: argparse.Namespace, *, cannot: Mapping[str, str] | None = None) -> OptimizeOptions:
    """The :class:`OptimizeOptions` of the options of :func:`add_optimize_options` in ``args``.

    Args:
        args: the parsed command line.
        cannot: ``args`` attribute (a key of :data:`OPTIMIZE_FLAGS`) -> why this command
            cannot honour that option; given, it is refused.

    Raises:
        ValueError: a refused option (naming it and why), a malformed ``--known`` or ``--set``.
    """
    from warpskill.optimizer import OptimizeOptions, parse_known  # torch and Warp: only for a command that optimises

    for name, why in (cannot or {}).items():
        if getattr(args, name) not in (None, False, []):
            raise ValueError(f"{OPTIMIZE_FLAGS[name]} cannot be used here: {why}")
    options = OptimizeOptions.build(device=args.device, seed=0 if args.seed is None else args.seed,
                                    init_only=args.init_only, known=parse_known(args.known),
                                    object_noun=args.object_noun, iterations=args.iterations)
    return options.with_settings(args.settings)


def holding_out(command: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """``command(args)`` holding the lock of its results folder ``args.out`` (waits while another
    command writes it: :meth:`~warpskill.contract.results_folder.ResultsFolder.locked`)."""

    @functools.wraps(command)
    def locked(args: argparse.Namespace) -> int:
        with ResultsFolder(args.out).locked():
            return command(args)

    return locked


def add_placement_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--offset", type=float, nargs=2, default=None, metavar=("X", "Y"),
                        help="fix the scene centre in the robot base frame [m] (default: searched; 0.5 0.0 "
                             "with --yaw alone)")
    parser.add_argument("--yaw", type=float, default=None,
                        help="fix the direction of the robot's forward axis in the world, about z [deg] "
                             "(default: searched; 90 with --offset alone)")


def add_robot_step_options(parser: argparse.ArgumentParser) -> None:
    """``--no-robot`` and the placement options: a command that plans and replays after reconstructing."""
    parser.add_argument("--no-robot", action="store_true", help="stop after the reconstruction (no Panda plan or replay)")
    add_placement_options(parser)


def robot_steps_wanted(args: argparse.Namespace) -> bool:
    """Whether to plan and replay: no ``--no-robot``, and the robot extra installed (else one line says how)."""
    return not args.no_robot and robot_steps_available()


def plan_robot(recon, args: argparse.Namespace):
    """The Panda's plan for ``recon`` placed as ``args`` say, or None where none is found (one line says why)."""
    try:
        return robot.retarget(recon, placement=placement(args))
    except robot.PlanError as error:
        print(f"retarget: stopped, no robot plan: {error}")
        return None


def placement(args):
    """``"auto"`` (the robot's base pose is searched) unless ``--offset`` or ``--yaw`` fix it."""
    if args.offset is None and args.yaw is None:
        return "auto"
    default = robot.Placement()
    offset = default.offset if args.offset is None else tuple(args.offset)
    yaw = default.yaw if args.yaw is None else math.radians(args.yaw)
    return robot.Placement(offset=offset, yaw=yaw)


def reconstruct(demos, folders: list[Path], checkpoint: Path, options: OptimizeOptions, *, quiet: bool = False,
                pictures: bool = True):
    """Optimise ``demos`` together with ``options`` (resuming ``checkpoint``); write each npz and
    pictures into its folder. A video well above 12 fps is optimised on every few of its frames
    (:func:`~warpskill.contract.frame_rate.at_optimiser_rate`): its reconstruction is at that rate."""
    from warpskill.engine import resolve_device  # torch and Warp: only for a command that optimises
    from warpskill.optimizer import optimize_many  # torch and Warp: only for a command that optimises

    resolve_device(options.device)  # a bad device is one error line before any work
    demos = [at_optimiser_rate(demo) for demo in demos]
    with contextlib.ExitStack() as holding:  # the checkpoint's folder and each output folder: this process alone
        for folder in sorted({checkpoint.parent, *folders}):
            holding.enter_context(ResultsFolder(folder).locked())
        reconstructions = optimize_many(demos, options, progress=not quiet, checkpoint=checkpoint)
        for demo, recon, out in zip(demos, reconstructions, folders):
            keeper = ResultsFolder(out)
            print(f"reconstruction: {keeper.save(recon, keeper.reconstruction)}")
            if pictures:
                for name, path in visual.save_pictures(recon, demo, out).items():
                    print(f"{name}: {path}")
                save_scene(recon, demo, out)
            report(recon, demo.action)
    return reconstructions


def report(recon, action) -> None:
    """Print whether ``recon`` meets ``action``'s success criteria, and which it fails (nothing
    without an action); then the hypotheses it was chosen from, where there were several."""
    if action:
        result = evaluate(recon, action)
        failed = [name for name, ok in result.checks.items() if not ok]
        verdict = "success" if result.success else "failure (" + ", ".join(failed) + ")"
        print(f"{action}: {verdict}")
    lines = hypothesis_lines(recon.judgements())
    if lines:
        print("\n".join(lines))


def hypothesis_lines(judged: list[dict]) -> list[str]:
    """A table of the simulated hypotheses (the reconstruction's ``hypotheses`` record), one line
    each under a heading; none for fewer than two (nothing was chosen)."""
    if len(judged) < 2:
        return []
    where = {None: "", True: "  ends behind the static", False: "  ends not behind the static"}
    lines = ["hypotheses (fit: the masks' loss after the contact, lower fits better):"]
    for item in judged:
        mark = "  (chosen)" if item["chosen"] else "  (ruled out by the masks)" if item["contradicted"] else ""
        lines.append(f"  {item['start']:<18s} contact {item['contact_frames']:3d} frames  fit {item['fit']:.3f}"
                     f"{where[item['ends_behind_static']]}{mark}")
    return lines


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


def save_scene(recon, demo, out: Path, plan=None, replay=None, *, frames=None, quiet: bool = False) -> None:
    """Write ``out/scene.rrd`` (the 3D Rerun recording, with the video ``frames`` when given) and
    say so; without rerun-sdk, say how to get it."""
    try:
        track = None if plan is None else robot.robot_track(plan, float(recon.fps), replay)
        path = visual.view(recon, demo, track, replay, frames=frames, path=out / "scene.rrd")
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


class StepClock:
    """Wall and process CPU seconds per step of a command (``prepare``, ``optimize``, ...), for
    the table a command prints at its end and ``timing.json`` (docs/formats.md). On a busy
    machine the CPU seconds are the steadier."""

    def __init__(self):
        self.steps: dict[str, dict[str, float]] = {}

    @contextlib.contextmanager
    def step(self, name: str):
        """Time the block as step ``name`` (a step timed twice adds up)."""
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            yield
        finally:
            step = self.steps.setdefault(name, {"seconds": 0.0, "cpu_seconds": 0.0})
            step["seconds"] += time.perf_counter() - wall
            step["cpu_seconds"] += time.process_time() - cpu

    def report(self, path: Path) -> None:
        """Print the seconds per step and their sum in one line; write them to ``path`` (JSON:
        ``{"steps": {name: {"seconds", "cpu_seconds"}}, "seconds", "cpu_seconds"}``, the sums)."""
        if not self.steps:
            return
        total = {key: sum(step[key] for step in self.steps.values()) for key in ("seconds", "cpu_seconds")}
        parts = ", ".join(f"{name} {step['seconds']:.1f}" for name, step in self.steps.items())
        print(f"seconds: {parts}; {total['seconds']:.1f} in all ({path})")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({"steps": self.steps, **total}, indent=1) + "\n")
