"""One run from the page: ``warpskill run`` on the clip and its outline, its lines read as
progress, then the robot's replay video.

The command runs in a process of its own (``python -c`` calling :func:`warpskill.cli.main`):
the page's server keeps its standard output, a crash stays in that process, and its lines
arrive as each step finishes.
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path
from typing import Callable

from warpskill.contract import Reconstruction, ResultsFolder

__all__ = ["RunSettings", "RunOutcome", "STEPS", "record_replay", "run_clip"]

STEPS = (
    ("prepare: the outline followed through the clip", "contact sheet:"),
    ("optimize: the scene reconstructed (physics)", "reconstruction:"),
    ("pictures: the overlay, the top view", "trajectories:"),
    ("retarget: the Panda's plan", "plan:"),
    ("replay: the plan simulated", "replay:"),
    ("scene: the 3D recording", "scene:"),
)
"""``warpskill run``'s steps as the page names them, each with the prefix of the line that ends it, in order."""

EXIT_MEANINGS = {0: "finished", 3: "stopped: no robot plan, or the replay fails the action's criteria",
                 2: "refused: the recording gives no demonstration", 1: "bad input"}
"""``warpskill run``'s exit statuses (warpskill/cli/run.py)."""


@dataclasses.dataclass(frozen=True)
class RunSettings:
    """What the page asks of ``warpskill run``.

    Attributes:
        action: one of :data:`warpskill.ACTIONS`.
        object_noun: what the object is (``--object-noun``), or None.
        iterations: physics-stage iterations (``--iterations``), None for the default.
        fps: the clip's frame rate [1/s] (``--fps``), None for the video's (12 for images).
        robot: plan and replay on the Panda (else ``--no-robot``).
    """

    action: str
    object_noun: str | None = None
    iterations: int | None = None
    fps: float | None = None
    robot: bool = True

    def arguments(self) -> list[str]:
        """The settings as ``warpskill run`` options."""
        options = ["--action", self.action, "--quiet"]
        if self.object_noun:
            options += ["--object-noun", self.object_noun]
        if self.iterations is not None:
            options += ["--iterations", str(self.iterations)]
        if self.fps is not None:
            options += ["--fps", repr(float(self.fps))]
        return options if self.robot else options + ["--no-robot"]


@dataclasses.dataclass(frozen=True)
class RunOutcome:
    """How a run ended: ``warpskill run``'s exit status, its lines, and what it says in one line."""

    status: int
    log: str

    @property
    def summary(self) -> str:
        """The error line of a refused run, a crash's last line, else the exit status's meaning and the last verdict."""
        lines = self.log.splitlines()
        errors = [line for line in lines if line.startswith("warpskill: error:")]
        if errors:
            return errors[-1]
        if "Traceback (most recent call last):" in lines:
            return f"crashed: {lines[-1]} (its traceback is in the lines below)"
        verdicts = [line for line in lines if ": success" in line or ": failure" in line]
        meaning = EXIT_MEANINGS.get(self.status, f"exit status {self.status}")
        return f"{meaning}; {verdicts[-1]}" if verdicts else meaning


def run_clip(clip: Path, outline: Path, out: Path, settings: RunSettings,
             on_step: Callable[[float, str], None]) -> RunOutcome:
    """Run ``warpskill run CLIP --polygons OUTLINE -o OUT`` with ``settings``.

    ``on_step(fraction, step)`` is called at the start and as each step ends (its line arrives):
    the fraction of :data:`STEPS` done, of ``len(STEPS) + 1`` (the page's own last step), and the
    step that starts.
    """
    command = [sys.executable, "-c", "import sys; from warpskill.cli import main; sys.exit(main())",
               "run", str(clip), "--polygons", str(outline), "-o", str(out), *settings.arguments()]
    on_step(0.0, STEPS[0][0])
    lines, done = [], 0
    environment = {**os.environ, "PYTHONUNBUFFERED": "1"}
    with subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          env=environment) as process:
        for line in process.stdout:
            lines.append(line)
            ended = [k for k in range(done, len(STEPS)) if line.startswith(STEPS[k][1])]
            if ended:
                done = ended[0] + 1
                on_step(done / (len(STEPS) + 1), STEPS[done][0] if done < len(STEPS) else "done")
    return RunOutcome(process.returncode, "".join(lines))


def record_replay(out: Path) -> Path | None:
    """Write the robot's replay video of the run in ``out`` (``replay.mp4``, or ``replay.png``
    without an offscreen renderer: :func:`warpskill.robot.record`); None without a finished replay."""
    from warpskill import robot  # MuJoCo: only once a run has replayed

    keeper = ResultsFolder(out)
    result = keeper.finished_replay() if keeper.plan.is_file() else None
    if result is None:
        return None
    robot.prefer_headless_gl()
    plan = robot.RobotPlan.load(keeper.plan)
    return robot.record(plan, plan.scene(Reconstruction.load(keeper.reconstruction)), result, out)
