"""The skill record: what one video teaches, relative to the objects, and the layout it is carried to.

A :class:`Skill` (``skill.npz`` beside the reconstruction, ``docs/formats.md``) holds the
action, the timing (grasp signal, contact onset and release [s]), the cuboid sizes, the
demonstrated layout, and the motion relative to the objects (the object's motion relative
to its start, the hand relative to the object, a ``put_*``'s release relative to the static
box), and what the object is (its noun: an open vessel is held by its rim at any layout).
A :class:`Layout` places the object's start and each static box on the table (x, y,
yaw) in the reconstruction's world frame.

Records and their file only: :mod:`warpskill.robot.skill_layout` derives a skill from a
reconstruction (``skill_from``) and carries it to a layout (``apply_skill``).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping

import numpy as np

from warpskill.contract.actions import check_action
from warpskill.contract.npz import read_npz, save_npz_atomic
from warpskill.contract.reconstruction import FIELD_SHAPES as RECONSTRUCTION_SHAPES
from warpskill.contract.reconstruction import SceneCounts

__all__ = ["FIELD_SHAPES", "OPTIONAL_FIELDS", "Layout", "LayoutError", "Skill", "SkillError"]

FIELD_SHAPES: dict[str, tuple[str | int, ...]] = {
    "action": (),
    "fps": (),
    "t": ("N",),
    "grasp": ("N",),
    "grasped": ("N",),
    "onset": (),
    "release": (),
    "object_size": (3,),
    "object_start_pos": (3,),
    "object_start_rot": (3, 3),
    "object_motion_pos": ("N", 3),
    "object_motion_rot": ("N", 3, 3),
    "hand_in_object_pos": ("N", 3),
    "hand_in_object_rot": ("N", 3, 3),
    "release_offset": (3,),
    "release_gap": (),
    # the scene around the motion, as the reconstruction holds it
    **{key: RECONSTRUCTION_SHAPES[key] for key in ("static_pos", "static_rot", "static_size", "camera_K",
                                                  "camera_elevation", "camera_height", "image_size", "loss")},
    "object_noun": (),
}
"""Every key of ``skill.npz`` and its shape; ``N`` frames and ``K`` static boxes."""

_STRING_FIELDS = ("action", "object_noun")

OPTIONAL_FIELDS = {"object_noun": ""}
"""Keys a file may lack (one written before the key), and the value they then take (noun unknown)."""


class SkillError(ValueError):
    """A skill file or record that breaks the contract (the message names the key)."""


class LayoutError(ValueError):
    """A layout the skill cannot be carried to; the one-line message says why.

    Attributes:
        reason: why in a few words (``"out of reach"``, ``"relation not met"``, ...): what a
            layout drawer counts its redrawn layouts by.
    """

    def __init__(self, message: str, reason: str = "refused") -> None:
        super().__init__(message)
        self.reason = reason


def _pose(value, what: str) -> tuple[float, float, float]:
    array = np.asarray(value, dtype=float)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise LayoutError(f"layout refused: {what} must be finite (x [m], y [m], yaw [rad]), got {value!r}")
    return tuple(float(v) for v in array)


@dataclasses.dataclass(frozen=True)
class Layout:
    """Where the skill is to run: the object's start and the static boxes, on the table.

    Attributes:
        object: (x [m], y [m], yaw [rad]) of the object's start in the reconstruction's world
            frame; yaw is the heading of the cuboid's local x (:func:`~warpskill.geometry.heading`).
        statics: one (x, y, yaw) per static box, in the reconstruction's order.
        object_size: (3,) [m] the object's edge lengths; None keeps the demonstrated size.

    Raises:
        LayoutError: a pose that is not three finite numbers, or a size not three positive ones.
    """

    object: tuple[float, float, float]
    statics: tuple[tuple[float, float, float], ...] = ()
    object_size: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "object", _pose(self.object, "the object's pose"))
        object.__setattr__(self, "statics", tuple(_pose(s, f"static box {k}'s pose")
                                                  for k, s in enumerate(self.statics)))
        if self.object_size is not None:
            size = np.asarray(self.object_size, dtype=float)
            if size.shape != (3,) or not np.all(np.isfinite(size)) or np.any(size <= 0):
                raise LayoutError(f"layout refused: the object size must be 3 positive lengths [m], "
                                  f"got {self.object_size!r}")
            object.__setattr__(self, "object_size", tuple(float(v) for v in size))

    def to_arrays(self, prefix: str = "layout_") -> dict[str, np.ndarray]:
        """The layout as ``.npz`` arrays: ``object`` (3,), ``static`` (K, 3), ``object_size`` (3,) if set."""
        arrays = {prefix + "object": np.array(self.object),
                  prefix + "static": np.array(self.statics, dtype=float).reshape(-1, 3)}
        if self.object_size is not None:
            arrays[prefix + "object_size"] = np.array(self.object_size)
        return arrays

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str = "layout_") -> "Layout | None":
        """The layout written by :meth:`to_arrays`, or None where ``arrays`` holds none."""
        if prefix + "object" not in arrays:
            return None
        size = arrays.get(prefix + "object_size")
        statics = np.asarray(arrays.get(prefix + "static", np.zeros((0, 3))), dtype=float).reshape(-1, 3)
        return cls(object=arrays[prefix + "object"], statics=tuple(map(tuple, statics)),
                   object_size=None if size is None else tuple(size))

    def describe(self) -> str:
        """The layout in one line (metres, degrees)."""
        def text(pose):
            return f"({pose[0]:.3f}, {pose[1]:.3f}, {math.degrees(pose[2]):.1f} deg)"
        statics = ", ".join(text(s) for s in self.statics) or "none"
        return f"object at {text(self.object)}, static boxes at {statics}"


@dataclasses.dataclass
class Skill(SceneCounts):
    """What a demonstration teaches, relative to the objects (keys and shapes: :data:`FIELD_SHAPES`).

    Build one with :func:`~warpskill.robot.skill_layout.skill_from`;
    :func:`~warpskill.robot.skill_layout.apply_skill` carries it to a :class:`Layout`.
    ``onset`` and ``release`` are the times [s] of the first held frame and of the frame after
    the last one (``nan``: held to the end). ``release_offset`` (3,) [m] is the released object's
    centre (the last frame's where held to the end) minus the static box's centre (world axes), ``release_gap`` [m] the gap between them
    along the relation's side (:mod:`warpskill.robot.skill_layout`'s doc; zeros and 0 for
    actions other than ``put_*``). ``object_noun`` is what the object is (the reconstruction's
    ``object_noun``; "" unknown): a layout's reconstruction carries it, so that an open vessel
    is held by its rim there as in the demonstration (:func:`~warpskill.robot.sizes.fit_sizes`).
    """

    action: str
    fps: float
    t: np.ndarray
    grasp: np.ndarray
    grasped: np.ndarray
    onset: float
    release: float
    object_size: np.ndarray
    object_start_pos: np.ndarray
    object_start_rot: np.ndarray
    object_motion_pos: np.ndarray
    object_motion_rot: np.ndarray
    hand_in_object_pos: np.ndarray
    hand_in_object_rot: np.ndarray
    release_offset: np.ndarray
    release_gap: float
    static_pos: np.ndarray
    static_rot: np.ndarray
    static_size: np.ndarray
    camera_K: np.ndarray
    camera_elevation: float
    camera_height: float
    image_size: np.ndarray
    loss: float
    object_noun: str = ""

    def __post_init__(self) -> None:
        _check_fields({name: getattr(self, name) for name in FIELD_SHAPES})
        self.action = check_action(str(self.action))
        self.object_noun = str(self.object_noun)

    def frames(self) -> tuple[int, int | None]:
        """The onset frame and the release frame (None: held to the end)."""
        k_on = int(round(self.onset * self.fps))
        return k_on, None if not np.isfinite(self.release) else int(round(self.release * self.fps))

    def save(self, path: str | os.PathLike) -> None:
        """Write ``skill.npz`` atomically: every key of :data:`FIELD_SHAPES`, but an unknown
        ``object_noun`` (left out, a file is written as before the key)."""
        save_npz_atomic(path, {name: np.asarray(getattr(self, name)) for name in FIELD_SHAPES
                               if name != "object_noun" or self.object_noun})

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Skill":
        """Read and check a ``skill.npz``; a missing optional key takes its :data:`OPTIONAL_FIELDS` value.

        Raises:
            SkillError: naming the file and the key, for a missing, unknown or malformed key.
            FileNotFoundError: ``path`` does not exist.
        """
        arrays = read_npz(path, SkillError)
        for name, default in OPTIONAL_FIELDS.items():
            arrays.setdefault(name, np.array(default))
        missing = [name for name in FIELD_SHAPES if name not in arrays]
        unknown = sorted(set(arrays) - set(FIELD_SHAPES))
        if missing or unknown:
            what = (f"missing key(s) {', '.join(missing)}" if missing else f"unknown key(s) {', '.join(unknown)}")
            raise SkillError(f"{path}: not a skill file, {what}")
        try:
            return cls(**{name: _scalar(arrays[name]) for name in FIELD_SHAPES})
        except ValueError as error:
            raise SkillError(f"{path}: {error}") from None


def _scalar(array: np.ndarray):
    """A 0-d array as a str or float, others as they are."""
    if array.ndim == 0:
        return str(array) if array.dtype.kind == "U" else float(array)
    return array


def _check_fields(fields: Mapping[str, object]) -> None:
    """Check every key's shape (``N``, ``K`` bound by the first key that has them) and finiteness."""
    dims: dict[str, int] = {}
    for name, template in FIELD_SHAPES.items():
        if name in _STRING_FIELDS:
            if np.ndim(fields[name]) != 0:
                raise SkillError(f"{name}: expected one string, got shape {np.shape(fields[name])}")
            continue
        array = np.asarray(fields[name])
        if array.dtype.kind not in "biuf":
            raise SkillError(f"{name}: expected numbers, got dtype {array.dtype}")
        shape_ok = array.ndim == len(template)
        for size, want in zip(array.shape, template):
            if isinstance(want, str):
                shape_ok = shape_ok and dims.setdefault(want, size) == size
            else:
                shape_ok = shape_ok and size == want
        if not shape_ok:
            raise SkillError(f"{name}: expected shape {template}, got {array.shape} (N = {dims.get('N')}, "
                             f"K = {dims.get('K')})")
        if name not in ("release",) and not np.all(np.isfinite(array)):
            raise SkillError(f"{name}: contains NaN or inf")
