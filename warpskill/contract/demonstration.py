"""The demonstration file of the data contract (``docs/formats.md``): what warpskill reads.

A demonstration is N frames of H x W binary masks (the hand, the manipulated object and
K static objects), a per-frame hand-object contact signal, the frame rate and the camera
intrinsics; optionally the action name and, for synthetic demonstrations, ground truth.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping, Sequence

import cv2
import numpy as np

from warpskill.contract.actions import check_action
from warpskill.contract.camera import Intrinsics
from warpskill.contract.npz import read_npz, save_npz_atomic
from warpskill.contract.reconstruction import ReconstructionError, check_fields

TRUTH_PREFIX = "truth_"
REQUIRED_KEYS = ("hand_mask", "object_mask", "contact", "fps")
OPTIONAL_KEYS = ("static_mask", "camera_K", "action", "object_noun", "static_nouns")


class DemonstrationError(ValueError):
    """A demonstration (file or arrays) that breaks the data contract."""


@dataclasses.dataclass
class Demonstration:
    """One demonstration, validated on construction.

    Construction accepts masks and contact as bool, 0/1 or 0/255 numbers and stores them
    as bool; see :meth:`from_arrays` for the file's optional forms (static mask without
    the K axis, ``camera_K`` or the default).

    Attributes:
        hand_mask: (N, H, W) bool, the hand/arm per frame.
        object_mask: (N, H, W) bool, the manipulated object per frame.
        static_mask: (K, N, H, W) bool, the static objects; K may be 0.
        contact: (N,) bool, frames where the hand touches the object.
        fps: frame rate [1/s].
        intrinsics: the camera's intrinsics for H x W images.
        action: one of :data:`warpskill.contract.actions.ACTIONS`, or None if unknown.
        truth: ground truth (synthetic demonstrations): reconstruction key (without the
            ``truth_`` prefix) -> array; empty if none.
        object_noun: what the manipulated object is, as annotated (e.g. ``"coffee mug"``;
            :func:`warpskill.nouns.typical.typical_size` gives its typical size), or None.
        static_nouns: what each static object is, (K,) strings or None per static, as
            annotated (e.g. ``"book"``); empty when no static is named.

    Raises:
        DemonstrationError: naming the key and the problem, for any input that breaks
            the contract. A mask that is empty in one frame is fine (not visible there);
            a hand or object mask empty in every frame, or a contact signal never on, is not.
    """

    hand_mask: np.ndarray
    object_mask: np.ndarray
    static_mask: np.ndarray
    contact: np.ndarray
    fps: float
    intrinsics: Intrinsics
    action: str | None = None
    truth: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    object_noun: str | None = None
    static_nouns: tuple[str | None, ...] = ()

    def __post_init__(self) -> None:
        self.hand_mask = _binary("hand_mask", self.hand_mask, ndim=3)
        n, h, w = self.hand_mask.shape
        self.object_mask = _binary("object_mask", self.object_mask, ndim=3)
        self.static_mask = _binary("static_mask", self.static_mask, ndim=4)
        self.contact = _binary("contact", self.contact, ndim=1)
        _check_shape("object_mask", self.object_mask.shape, (n, h, w), "(N, H, W)")
        _check_shape("static_mask", self.static_mask.shape[1:], (n, h, w), "(K, N, H, W)")
        _check_shape("contact", self.contact.shape, (n,), "(N,)")
        for key, mask in (("hand_mask", self.hand_mask), ("object_mask", self.object_mask)):
            if not mask.any():
                raise DemonstrationError(f"{key}: empty in every frame (nothing visible anywhere)")
        if not self.contact.any():
            raise DemonstrationError("contact: never on (the hand must touch the object in some frame)")
        self.fps = _positive_scalar("fps", self.fps)
        _check_intrinsics(self.intrinsics, (h, w))
        if self.action is not None:
            try:
                check_action(self.action)
            except ValueError as exc:
                raise DemonstrationError(f"action: {exc}") from None
        if self.object_noun is not None and not isinstance(self.object_noun, str):
            raise DemonstrationError(f"object_noun: expected a string, got {type(self.object_noun).__name__}")
        self.static_nouns = _static_nouns(self.static_nouns, self.num_static)
        try:
            self.truth = check_fields(self.truth, dims={"N": n, "K": self.num_static}, key_prefix=TRUTH_PREFIX)
        except ReconstructionError as exc:
            raise DemonstrationError(str(exc)) from None

    @classmethod
    def from_arrays(
        cls,
        hand_mask: np.ndarray,
        object_mask: np.ndarray,
        contact: np.ndarray,
        fps: float,
        *,
        static_mask: np.ndarray | None = None,
        camera_K: np.ndarray | None = None,
        action: str | None = None,
        truth: dict[str, np.ndarray] | None = None,
        object_noun: str | None = None,
        static_nouns: Sequence[str | None] = (),
    ) -> "Demonstration":
        """Build a demonstration from the arrays of a demonstration file.

        Args:
            hand_mask: (N, H, W) bool, 0/1 or 0/255.
            object_mask: (N, H, W) bool, 0/1 or 0/255.
            contact: (N,) bool or 0/1.
            fps: frame rate [1/s], > 0.
            static_mask: (N, H, W) for one static object or (K, N, H, W); None for none.
            camera_K: (3, 3) intrinsics [px]; None for the paper's default.
            action: action name, or None if unknown.
            truth: ground-truth reconstruction fields, keyed without the ``truth_`` prefix.
            object_noun: the manipulated object's noun, or None if unknown.
            static_nouns: each static object's noun (None: unknown), K of them, or none.

        Raises:
            DemonstrationError: naming the key and the problem.
        """
        hand_mask = _binary("hand_mask", hand_mask, ndim=3)
        n, h, w = hand_mask.shape
        if static_mask is None:
            static_mask = np.zeros((0, n, h, w), dtype=bool)
        elif np.ndim(static_mask) == 3:
            static_mask = np.asarray(static_mask)[None]
        if camera_K is None:
            intrinsics = Intrinsics.default(h, w)
        else:
            intrinsics = Intrinsics(_finite_floats("camera_K", camera_K), (h, w))
        return cls(hand_mask, object_mask, static_mask, contact, fps, intrinsics, action, dict(truth or {}), object_noun,
                   tuple(static_nouns))

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Demonstration":
        """Read and validate a demonstration ``.npz``.

        Raises:
            DemonstrationError: naming the file, the key and the problem, for a file that
                is not an ``.npz`` archive, a missing required key, an unknown key or a
                bad array.
            FileNotFoundError: ``path`` does not exist.
        """
        arrays = read_npz(path, DemonstrationError)
        try:
            return cls.from_file_arrays(arrays)
        except DemonstrationError as exc:
            raise DemonstrationError(f"{path}: {exc}") from None

    @classmethod
    def from_file_arrays(cls, arrays: Mapping[str, np.ndarray]) -> "Demonstration":
        """:meth:`from_arrays` of a file's arrays, keyed as in ``docs/formats.md`` (truth as ``truth_*``).

        Raises:
            DemonstrationError: a missing required key, an unknown key, or naming the key and the problem.
        """
        missing = [key for key in REQUIRED_KEYS if key not in arrays]
        if missing:
            raise DemonstrationError(f"missing required key(s) {', '.join(missing)}")
        known = REQUIRED_KEYS + OPTIONAL_KEYS
        unknown = sorted(key for key in arrays if key not in known and not key.startswith(TRUTH_PREFIX))
        if unknown:
            valid = ", ".join(known + (TRUTH_PREFIX + "*",))
            raise DemonstrationError(f"unknown key(s) {', '.join(unknown)}; valid keys: {valid}")
        truth = {key[len(TRUTH_PREFIX) :]: value for key, value in arrays.items() if key.startswith(TRUTH_PREFIX)}
        return cls.from_arrays(
            arrays["hand_mask"],
            arrays["object_mask"],
            arrays["contact"],
            arrays["fps"],
            static_mask=arrays.get("static_mask"),
            camera_K=arrays.get("camera_K"),
            action=_optional_string("action", arrays.get("action")),
            truth=truth,
            object_noun=_optional_string("object_noun", arrays.get("object_noun")),
            static_nouns=_file_static_nouns(arrays.get("static_nouns")),
        )

    def save(self, path: str | os.PathLike) -> None:
        """Write the demonstration ``.npz`` to ``path`` atomically.

        Masks and contact are written as uint8 0/1, ``static_mask`` as (K, N, H, W) and
        only when K > 0, ``camera_K`` always, ``action`` and ``object_noun`` when known,
        ``static_nouns`` ((K,) str, "" for an unnamed static) when any static is named,
        truth as ``truth_*``.
        """
        arrays = {
            "hand_mask": self.hand_mask.astype(np.uint8),
            "object_mask": self.object_mask.astype(np.uint8),
            "contact": self.contact.astype(np.uint8),
            "fps": np.array(self.fps),
            "camera_K": self.intrinsics.K,
        }
        if self.num_static:
            arrays["static_mask"] = self.static_mask.astype(np.uint8)
        if self.action is not None:
            arrays["action"] = np.array(self.action)
        if self.object_noun is not None:
            arrays["object_noun"] = np.array(self.object_noun)
        if any(self.static_nouns):
            arrays["static_nouns"] = np.array([noun or "" for noun in self.static_nouns])
        arrays.update({TRUTH_PREFIX + name: value for name, value in self.truth.items()})
        save_npz_atomic(path, arrays)

    @property
    def num_frames(self) -> int:
        """N, the number of frames."""
        return self.hand_mask.shape[0]

    @property
    def image_size(self) -> tuple[int, int]:
        """(H, W) [px]."""
        return self.hand_mask.shape[1], self.hand_mask.shape[2]

    @property
    def num_static(self) -> int:
        """K, the number of static objects."""
        return self.static_mask.shape[0]

    @property
    def duration(self) -> float:
        """Time from the first to the last frame [s], (N - 1) / fps."""
        return (self.num_frames - 1) / self.fps

    def mask_channels(self) -> np.ndarray:
        """All masks at full size, (N, 2 + K, H, W) bool: channel 0 the hand, 1 the object, 2 + k
        static object k (:meth:`mask_stack`'s channels, unresized and not converted to floats)."""
        statics = self.static_mask.transpose(1, 0, 2, 3)
        return np.concatenate([self.hand_mask[:, None], self.object_mask[:, None], statics], axis=1)

    def mask_stack(self, height: int, width: int) -> np.ndarray:
        """All masks area-averaged to ``height`` x ``width``: what the optimiser fits.

        Returns:
            (N, 2 + K, height, width) float32 in [0, 1]: channel 0 the hand, 1 the object,
            2 + k static object k; each value the covered fraction of the output pixel.
        """
        channels = [self.hand_mask, self.object_mask, *self.static_mask]
        return np.stack([_area_resize(masks, height, width) for masks in channels], axis=1)

    def resized(self, height: int, width: int) -> "Demonstration":
        """The demonstration at ``height`` x ``width``: pixels at least half covered stay set.

        Intrinsics are rescaled to match (:meth:`Intrinsics.resized`); contact, fps,
        action and truth are unchanged.

        Raises:
            DemonstrationError: the hand or object vanishes in every frame at this size.
        """
        return dataclasses.replace(
            self,
            hand_mask=_area_resize(self.hand_mask, height, width) >= 0.5,
            object_mask=_area_resize(self.object_mask, height, width) >= 0.5,
            static_mask=_area_resize(self.static_mask, height, width) >= 0.5,
            intrinsics=self.intrinsics.resized(height, width),
        )


def _binary(key: str, value: object, *, ndim: int) -> np.ndarray:
    """``value`` as a bool array of ``ndim`` dims; accepts bool, 0/1 and 0/255 numbers."""
    array = np.asarray(value)
    if array.ndim != ndim:
        raise DemonstrationError(f"{key}: expected {ndim} dimensions, got shape {array.shape}")
    if array.dtype.kind == "b":
        return array
    if array.dtype.kind not in "iuf":
        raise DemonstrationError(f"{key}: expected bool, 0/1 or 0/255 values, got dtype {array.dtype}")
    if array.dtype.kind == "f" and not np.all(np.isfinite(array)):
        raise DemonstrationError(f"{key}: contains NaN or inf")
    zero = array == 0
    if np.all(zero | (array == 1)) or np.all(zero | (array == 255)):
        return ~zero
    stray = array[~zero & (array != 1) & (array != 255)]
    found = f"value {stray.flat[0]}" if stray.size else "both 1 and 255"
    raise DemonstrationError(f"{key}: expected bool, 0/1 or 0/255 values, found {found}")


def _check_shape(key: str, shape: tuple[int, ...], expected: tuple[int, ...], template: str) -> None:
    """Raise unless a mask's ``shape`` agrees with the N, H, W of ``hand_mask``."""
    if tuple(shape) != tuple(expected):
        raise DemonstrationError(
            f"{key}: expected shape {template} with (N, H, W) of hand_mask = {expected}, got {shape}"
        )


def _finite_floats(key: str, value: object) -> np.ndarray:
    """``value`` as a float64 array; raises unless numeric and finite."""
    array = np.asarray(value)
    if array.dtype.kind not in "iuf":
        raise DemonstrationError(f"{key}: expected numbers, got dtype {array.dtype}")
    if not np.all(np.isfinite(array)):
        raise DemonstrationError(f"{key}: contains NaN or inf")
    return array.astype(np.float64)


def _positive_scalar(key: str, value: object) -> float:
    """``value`` as a float; raises unless a finite number > 0 with no dimensions."""
    array = _finite_floats(key, value)
    if array.ndim != 0:
        raise DemonstrationError(f"{key}: expected a scalar, got shape {array.shape}")
    if not array > 0:
        raise DemonstrationError(f"{key}: must be > 0, got {float(array)}")
    return float(array)


def _check_intrinsics(intrinsics: Intrinsics, image_size: tuple[int, int]) -> None:
    """Raise unless ``intrinsics`` is a pinhole K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] for the masks."""
    if not isinstance(intrinsics, Intrinsics):
        raise DemonstrationError(f"camera_K: expected Intrinsics, got {type(intrinsics).__name__}")
    K = _finite_floats("camera_K", intrinsics.K)
    if K.shape != (3, 3):
        raise DemonstrationError(f"camera_K: expected shape (3, 3), got {K.shape}")
    zero_entries = K[[0, 1, 2, 2], [1, 0, 0, 1]]
    if np.any(np.abs(zero_entries) > 1e-9) or abs(K[2, 2] - 1.0) > 1e-9:
        raise DemonstrationError(f"camera_K: expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], got {K.tolist()}")
    if not (K[0, 0] > 0 and K[1, 1] > 0):
        raise DemonstrationError(f"camera_K: focal lengths must be > 0, got fx = {K[0, 0]}, fy = {K[1, 1]}")
    if tuple(intrinsics.image_size) != tuple(image_size):
        raise DemonstrationError(
            f"camera_K: intrinsics are for {intrinsics.image_size} (H, W) images, the masks are {image_size}"
        )


def _optional_string(key: str, value: np.ndarray | None) -> str | None:
    """A 0-d str array read from a file as a Python str (None stays None)."""
    if value is None:
        return None
    if value.dtype.kind != "U" or value.ndim != 0:
        raise DemonstrationError(f"{key}: expected a string (0-d str array), got {value.dtype} of shape {value.shape}")
    return str(value)


def _static_nouns(nouns: Sequence[str | None], num_static: int) -> tuple[str | None, ...]:
    """``nouns`` checked as K strings or None, one per static ("" read as None); () stays ()."""
    nouns = tuple(nouns)
    if nouns and len(nouns) != num_static:
        raise DemonstrationError(f"static_nouns: {len(nouns)} noun(s) for {num_static} static object(s)")
    if any(noun is not None and not isinstance(noun, str) for noun in nouns):
        raise DemonstrationError(f"static_nouns: expected strings or None, got {nouns!r}")
    return tuple(noun or None for noun in nouns) if any(nouns) else ()


def _file_static_nouns(value: np.ndarray | None) -> tuple[str, ...]:
    """A file's (K,) str array of static nouns as a tuple ("" for an unnamed static); None: ()."""
    if value is None:
        return ()
    if value.dtype.kind != "U" or value.ndim != 1:
        raise DemonstrationError(f"static_nouns: expected (K,) strings, got {value.dtype} of shape {value.shape}")
    return tuple(str(noun) for noun in value)


def _area_resize(masks: np.ndarray, height: int, width: int) -> np.ndarray:
    """Area-average bool masks (..., H, W) to (..., height, width) float32 in [0, 1] (cv2.INTER_AREA)."""
    if height < 1 or width < 1:
        raise ValueError(f"output size must be positive, got {height} x {width}")
    if masks.shape[-2:] == (height, width):
        return masks.astype(np.float32)
    images = masks.reshape(-1, *masks.shape[-2:])
    resized = np.empty((len(images), height, width), dtype=np.float32)
    for image, out in zip(images, resized):  # one image at a time: no full-size float copy of the stack
        out[...] = cv2.resize(image.astype(np.float32), (width, height), interpolation=cv2.INTER_AREA)
    return resized.reshape(*masks.shape[:-2], height, width)
