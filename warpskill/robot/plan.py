"""A robot plan: time-stamped Panda joint positions and gripper openings, saved as ``.npz`` and CSV.

Keys of the plan ``.npz`` (units: seconds, radians, metres):

| key | shape | meaning |
| --- | --- | --- |
| ``t`` | (T,) | time of each sample from the plan's start |
| ``q`` | (T, 7) | arm joint positions ``panda_joint1`` .. ``panda_joint7`` |
| ``gripper`` | (T,) | commanded gripper opening (finger distance, 0 = closed) |
| ``tcp`` | (T, 4, 4) | planned tool-centre-point pose in the reconstruction's world |
| ``grasp_time``, ``release_time`` | () | when the gripper starts closing / opening (nan: never) |
| ``start_time`` | () | plan time of the reconstruction's first frame (after the lead-in) |
| ``recon_time`` | (T,) | reconstruction time each sample follows (pauses repeat a time) |
| ``base`` | (4, 4) | robot base pose in the world |
| ``grasp_pose`` | (4, 4) | the chosen grasp or push pose in the object's frame |
| ``grasp_name`` | () str | its name (e.g. ``top_x``, ``push_-x``) |
| ``grasp_kind`` | () str | ``grasp`` (closes on the object) or ``push`` (closed fingers press it) |
| ``action`` | () str | the reconstruction's action |
| ``offset``, ``yaw`` | (2,), () | the placement: scene centre in the base frame [m], the base's heading [rad] |
| ``placement`` | () str | ``auto`` (searched) or ``given`` |
| ``object_size``, ``object_pos``, ``object_rot`` | (3,), (F, 3), (F, 3, 3) | the object the robot handles: its size, centre path and (upright) rotations (reconstruction frames); one carried into view rests until the robot takes it |
| ``static_size``, ``static_pos``, ``static_rot`` | (K, 3), (K, 3), (K, 3, 3) | the static cuboids the robot works with |
| ``note`` | () str | what was changed for the robot (a substituted object, a rim grasp), or empty |
| ``object_noun`` | () str | what the object is (the reconstruction's ``object_noun``): an open vessel is simulated open (:func:`~warpskill.robot.model.object_boxes`); absent: unknown |
| ``layout_object``, ``layout_static``, ``layout_object_size`` | (3,), (K, 3), (3,) | the :class:`~warpskill.contract.skill.Layout` the skill was carried to (x, y, yaw); absent: the demonstrated layout |

The sizes and poses are those the replays simulate (:meth:`RobotPlan.scene`); plans
without them (older files) replay the reconstruction's. A plan with a layout replays the
reconstruction's skill carried to it (:func:`~warpskill.robot.skill_layout.apply_skill`).

The CSV has one row per sample: ``t, q1..q7, gripper, phase`` where ``phase`` is
``approach``, ``grasp``, ``hold``, ``release`` or ``retreat``.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from warpskill.contract.npz import read_npz, save_npz_atomic
from warpskill.contract.skill import Layout
from warpskill.robot.skill_layout import apply_skill, skill_from


class PlanError(ValueError):
    """No admissible robot motion: an unreachable target or no feasible grasp (the message names the frame)."""


@dataclasses.dataclass
class RobotPlan:
    """Time-stamped joint positions of the Panda for one reconstruction (see the module doc for keys)."""

    t: np.ndarray
    q: np.ndarray
    gripper: np.ndarray
    tcp: np.ndarray
    grasp_time: float
    release_time: float
    start_time: float
    recon_time: np.ndarray
    base: np.ndarray
    grasp_pose: np.ndarray
    grasp_name: str
    grasp_kind: str
    action: str
    planning_time: float = float("nan")
    offset: np.ndarray | None = None
    yaw: float = float("nan")
    placement: str = ""
    object_size: np.ndarray | None = None
    object_pos: np.ndarray | None = None
    object_rot: np.ndarray | None = None
    static_size: np.ndarray | None = None
    static_pos: np.ndarray | None = None
    static_rot: np.ndarray | None = None
    note: str = ""
    object_noun: str = ""
    layout: Layout | None = None

    @property
    def num_samples(self) -> int:
        """T, the number of samples."""
        return self.t.shape[0]

    @property
    def dt(self) -> float:
        """Sample period [s]."""
        return float(self.t[1] - self.t[0])

    def scene(self, recon):
        """``recon`` with the cuboids the plan was made for (the sizes and poses it handles, the object's start too).

        A plan made for a layout first carries ``recon``'s skill there (the hand's path too).
        """
        if self.layout is not None:
            recon = apply_skill(skill_from(recon), self.layout)
        if self.object_size is None:
            return recon
        changes = {name: np.asarray(getattr(self, name), float) for name in
                   ("object_size", "object_pos", "object_rot", "static_size", "static_pos", "static_rot")
                   if getattr(self, name) is not None}
        for name in ("object_pos", "object_rot"):
            if name in changes and len(changes[name]) != recon.num_frames:
                changes.pop(name)
        if self.object_noun:
            changes["object_noun"] = np.array(self.object_noun)
        same = all(_same(value, getattr(recon, name)) for name, value in changes.items())
        return recon if same else dataclasses.replace(recon, **changes)

    def phases(self) -> np.ndarray:
        """(T,) phase name of each sample: approach, grasp, hold, release, retreat."""
        phase = np.full(self.num_samples, "approach", dtype=object)
        if np.isfinite(self.grasp_time):
            phase[self.t >= self.grasp_time] = "grasp"
            phase[self.t >= self.grasp_time + CLOSE_TIME] = "hold"
        if np.isfinite(self.release_time):
            phase[self.t >= self.release_time] = "release"
            phase[self.t >= self.release_time + OPEN_TIME] = "retreat"
        return phase

    def save(self, path: str | os.PathLike) -> None:
        """Write the plan ``.npz`` atomically to ``path``."""
        arrays = {field.name: np.asarray(getattr(self, field.name)) for field in dataclasses.fields(self)
                  if getattr(self, field.name) is not None and field.name != "layout"}
        if self.layout is not None:
            arrays.update(self.layout.to_arrays())
        save_npz_atomic(path, arrays)

    def save_csv(self, path: str | os.PathLike) -> None:
        """Write ``t, q1..q7, gripper, phase`` rows to ``path``."""
        header = "t," + ",".join(f"q{i}" for i in range(1, 8)) + ",gripper,phase"
        rows = [header]
        for t, q, g, phase in zip(self.t, self.q, self.gripper, self.phases()):
            rows.append(f"{t:.4f}," + ",".join(f"{v:.6f}" for v in q) + f",{g:.5f},{phase}")
        Path(path).write_text("\n".join(rows) + "\n")

    @classmethod
    def load(cls, path: str | os.PathLike) -> "RobotPlan":
        """Read a plan ``.npz`` written by :meth:`save`.

        Raises:
            PlanError: a missing key.
        """
        arrays = read_npz(path, PlanError)
        names = [field.name for field in dataclasses.fields(cls)]
        optional = {field.name for field in dataclasses.fields(cls) if field.default is not dataclasses.MISSING}
        missing = [name for name in names if name not in arrays and name not in optional]
        if missing:
            raise PlanError(f"{path}: not a robot plan, missing key(s) {', '.join(missing)}")
        kwargs = {"layout": Layout.from_arrays(arrays)}
        for name in names:
            if name not in arrays:
                continue
            value = arrays[name]
            if name in ("grasp_name", "grasp_kind", "action", "placement", "note", "object_noun"):
                value = str(value)
            elif value.ndim == 0 and name != "offset":
                value = float(value)
            kwargs[name] = value
        return cls(**kwargs)


def _same(value: np.ndarray, given: np.ndarray) -> bool:
    """Whether a plan's field equals the reconstruction's (numbers within ``np.allclose``'s tolerance)."""
    if np.shape(value) != np.shape(given):
        return False
    return bool(np.array_equal(value, given) if value.dtype.kind == "U" else np.allclose(value, given))


CLOSE_TIME = 0.6  # [s] the gripper closes (and the arm waits) at the grasp
OPEN_TIME = 0.5  # [s] the gripper opens (and the arm waits) at the release
