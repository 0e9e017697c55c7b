"""The reconstruction file of the data contract (``docs/formats.md``): what warpskill outputs.

A reconstruction holds, per frame k of N, the hand tip pose and grasp signal, the
manipulated cuboid's pose, and the K static cuboids and camera found for the whole video.
Units: metres, seconds, radians; poses in the world frame (z up, ground z = 0).
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping

import numpy as np

from warpskill.contract.actions import check_action
from warpskill.contract.npz import read_npz, save_npz_atomic
from warpskill.geometry import cuboid_corners

FIELD_SHAPES: dict[str, tuple[str | int, ...]] = {
    "fps": (),
    "t": ("N",),
    "hand_pos": ("N", 3),
    "hand_rot": ("N", 3, 3),
    "grasp": ("N",),
    "grasped": ("N",),
    "object_pos": ("N", 3),
    "object_rot": ("N", 3, 3),
    "object_size": (3,),
    "static_pos": ("K", 3),
    "static_rot": ("K", 3, 3),
    "static_size": ("K", 3),
    "camera_K": (3, 3),
    "camera_elevation": (),
    "camera_height": (),
    "image_size": (2,),
    "action": (),
    "loss": (),
    "options": (),
    "object_noun": (),
    "hypotheses": (),
}
"""Every reconstruction key and its shape; ``N`` frames and ``K`` static objects."""

_INTEGER_FIELDS = ("image_size",)
_STRING_FIELDS = ("action", "options", "object_noun", "hypotheses")
OPTIONAL_FIELDS = {"action": "", "options": "", "object_noun": "", "hypotheses": ""}
"""Keys a file may lack, and the value they then take (unknown action; options, noun, hypotheses not recorded)."""
_OMITTED_WHEN_EMPTY = ("object_noun", "hypotheses")


class ReconstructionError(ValueError):
    """A reconstruction (file or arrays) that breaks the data contract."""


def check_fields(
    fields: Mapping[str, object], *, dims: Mapping[str, int] | None = None, key_prefix: str = ""
) -> dict[str, np.ndarray]:
    """Validate some or all reconstruction fields and return them as NumPy arrays.

    Numbers become float64 arrays (``image_size`` int64), ``action`` a 0-d str array
    (``None`` becomes ``""``, meaning unknown).

    Args:
        fields: field name -> array-like; any subset of :data:`FIELD_SHAPES`.
        dims: sizes fixed in advance for ``N`` and/or ``K``; a size not given here is
            taken from the first field that has it.
        key_prefix: prepended to field names in error messages (``"truth_"``).

    Raises:
        ReconstructionError: naming the key, for an unknown name, a wrong dtype or shape,
            a non-finite number, ``fps`` <= 0, a non-positive ``image_size`` or an
            unknown action.
    """
    known = {symbol: (size, "") for symbol, size in (dims or {}).items()}
    checked = {}
    for name, value in fields.items():
        key = key_prefix + name
        if name not in FIELD_SHAPES:
            raise ReconstructionError(f"{key}: not a reconstruction key; valid keys: {', '.join(FIELD_SHAPES)}")
        array = _typed_array(key, name, value)
        _check_shape(key, array.shape, FIELD_SHAPES[name], known)
        checked[name] = array
    fps = checked.get("fps")
    if fps is not None and not fps > 0:
        raise ReconstructionError(f"{key_prefix}fps: must be > 0, got {fps}")
    image_size = checked.get("image_size")
    if image_size is not None and not np.all(image_size > 0):
        raise ReconstructionError(f"{key_prefix}image_size: must be positive (H, W), got {image_size.tolist()}")
    return checked


def _typed_array(key: str, name: str, value: object) -> np.ndarray:
    """``value`` as an array of the field's kind (str, int64 or float64), finite."""
    if name in _STRING_FIELDS:
        array = np.asarray("" if value is None else value)
        if array.dtype.kind != "U":
            raise ReconstructionError(f"{key}: expected a string, got dtype {array.dtype}")
        if name == "action" and array.ndim == 0 and str(array):
            try:
                check_action(str(array))
            except ValueError as exc:
                raise ReconstructionError(f"{key}: {exc}") from None
        return array
    array = np.asarray(value)
    if array.dtype.kind not in "biuf":
        raise ReconstructionError(f"{key}: expected numbers, got dtype {array.dtype}")
    if name in _INTEGER_FIELDS:
        if array.dtype.kind not in "iu":
            raise ReconstructionError(f"{key}: expected integers, got dtype {array.dtype}")
        return array.astype(np.int64)
    array = array.astype(np.float64)
    if not np.all(np.isfinite(array)):
        raise ReconstructionError(f"{key}: contains NaN or inf")
    return array


def _check_shape(
    key: str, shape: tuple[int, ...], template: tuple[str | int, ...], known: dict[str, tuple[int, str]]
) -> None:
    """Check ``shape`` against ``template``; ``known``: symbol -> (size, key it came from or "").

    A symbolic size seen for the first time is bound to ``key``'s size.
    """
    expected = "(" + ", ".join(map(str, template)) + ("," if len(template) == 1 else "") + ")"
    if len(shape) != len(template):
        raise ReconstructionError(f"{key}: expected shape {expected}, got {shape}")
    for size, want in zip(shape, template):
        if isinstance(want, int):
            if size != want:
                raise ReconstructionError(f"{key}: expected shape {expected}, got {shape}")
        elif want not in known:
            known[want] = (size, key)
        elif known[want][0] != size:
            bound, source = known[want]
            origin = f" (from {source})" if source else ""
            raise ReconstructionError(f"{key}: expected shape {expected} with {want} = {bound}{origin}, got {shape}")


class SceneCounts:
    """``num_frames`` and ``num_static`` of a record with per-frame times ``t`` (N,) and
    static positions ``static_pos`` (K, 3)."""

    t: np.ndarray
    static_pos: np.ndarray

    @property
    def num_frames(self) -> int:
        """N, the number of frames."""
        return self.t.shape[0]

    @property
    def num_static(self) -> int:
        """K, the number of static objects."""
        return self.static_pos.shape[0]


@dataclasses.dataclass
class Reconstruction(SceneCounts):
    """Hand, object, static objects and camera found for one demonstration.

    Fields are exactly the reconstruction keys of ``docs/formats.md``; shapes in
    :data:`FIELD_SHAPES`. Construction validates and converts every field (see
    :func:`check_fields`); ``action`` may be given as ``None`` or ``""`` when unknown.
    """

    fps: np.ndarray
    t: np.ndarray
    hand_pos: np.ndarray
    hand_rot: np.ndarray
    grasp: np.ndarray
    grasped: np.ndarray
    object_pos: np.ndarray
    object_rot: np.ndarray
    object_size: np.ndarray
    static_pos: np.ndarray
    static_rot: np.ndarray
    static_size: np.ndarray
    camera_K: np.ndarray
    camera_elevation: np.ndarray
    camera_height: np.ndarray
    image_size: np.ndarray
    action: np.ndarray
    loss: np.ndarray
    #: JSON of the optimisation options that made it (``OptimizeOptions.to_json``); "" if not recorded
    options: np.ndarray = dataclasses.field(default_factory=lambda: np.array(""))
    #: what the manipulated object is, as annotated (the demonstration's ``object_noun``); "" if unknown
    object_noun: np.ndarray = dataclasses.field(default_factory=lambda: np.array(""))
    #: JSON list of the simulated hypotheses it was chosen from, one object each (``start``,
    #: ``contact_frames``, ``fit``, ``ends_behind_static``, ``contradicted``, ``chosen``); "" if not recorded
    hypotheses: np.ndarray = dataclasses.field(default_factory=lambda: np.array(""))

    def __post_init__(self) -> None:
        fields = {name: getattr(self, name) for name in FIELD_SHAPES}
        for name, array in check_fields(fields).items():
            setattr(self, name, array)
        if self.num_frames == 0:
            raise ReconstructionError("t: expected at least one frame, got shape (0,)")
        self.judgements()  # a record that does not parse is refused here, not where it is read

    def judgements(self) -> list[dict]:
        """The ``hypotheses`` record as a list of dicts (empty when not recorded).

        Raises:
            ReconstructionError: the record is not a JSON list of objects.
        """
        text = str(self.hypotheses)
        try:
            judged = json.loads(text) if text else []
        except json.JSONDecodeError as exc:
            raise ReconstructionError(f"hypotheses: not JSON ({exc})") from None
        if not isinstance(judged, list) or not all(isinstance(item, dict) for item in judged):
            raise ReconstructionError("hypotheses: expected a JSON list of objects")
        return judged

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Reconstruction":
        """Read and validate a reconstruction ``.npz``; a missing ``action`` means unknown.

        Raises:
            ReconstructionError: naming the key, for a missing or unknown key or a bad
                array; or for a file that is not an ``.npz`` archive.
            FileNotFoundError: ``path`` does not exist.
        """
        arrays = read_npz(path, ReconstructionError)
        for name, default in OPTIONAL_FIELDS.items():
            arrays.setdefault(name, np.array(default))
        missing = [name for name in FIELD_SHAPES if name not in arrays]
        if missing:
            raise ReconstructionError(f"{path}: missing key(s) {', '.join(missing)}")
        unknown = sorted(set(arrays) - set(FIELD_SHAPES))
        if unknown:
            raise ReconstructionError(f"{path}: unknown key(s) {', '.join(unknown)}")
        try:
            return cls(**arrays)
        except ReconstructionError as exc:
            raise ReconstructionError(f"{path}: {exc}") from None

    def save(self, path: str | os.PathLike) -> None:
        """Write the reconstruction ``.npz`` to ``path`` atomically (compressed): every key, but an
        unknown ``object_noun`` and unrecorded ``hypotheses`` (left out, a file is written as before those keys)."""
        save_npz_atomic(path, {name: getattr(self, name) for name in FIELD_SHAPES
                               if name not in _OMITTED_WHEN_EMPTY or str(getattr(self, name))})

    def object_corners(self) -> np.ndarray:
        """(N, 8, 3) world corners [m] of the manipulated cuboid in every frame."""
        return cuboid_corners(self.object_pos, self.object_rot, self.object_size)

    def static_corners(self) -> np.ndarray:
        """(K, 8, 3) world corners [m] of the static cuboids."""
        return cuboid_corners(self.static_pos, self.static_rot, self.static_size)
