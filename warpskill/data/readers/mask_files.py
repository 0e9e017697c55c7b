"""Readers of the masks people actually have, into a :class:`Demonstration`.

- :func:`read_label_images`: a folder of per-frame label images (an index or a colour per
  object), e.g. the output of a video segmenter such as STCN or XMem;
- :func:`read_mask_folders`: one binary image per object and frame, in per-object folders;
- :func:`read_masks`: either of the two, as raw (hand, object, static) mask stacks;
- :func:`read_video_demonstration`: a video file (OpenCV) plus masks in either form; it also
  returns the video's frames, for :func:`warpskill.visual.pictures.save_pictures` ``background=``.

Bounding-box annotations (Something-Else) are in :mod:`warpskill.data.boxes`.

Masks pass through :func:`warpskill.data.masks.clean_masks` (the largest blob per frame). The
contact signal is given, read from a detections CSV (:mod:`.contact_files`), or estimated
from the masks (:mod:`warpskill.data.contact`).
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from warpskill.contract.demonstration import Demonstration, DemonstrationError
from warpskill.data.contact import estimate_contact
from warpskill.data.masks import DEFAULT_MIN_AREA_FRACTION, clean_masks
from warpskill.data.readers.contact_files import read_detections
from warpskill.data.readers.video import read_video

IMAGE_SUFFIXES = (".png", ".bmp", ".tif", ".tiff")
"""Lossless formats read as masks (JPEG's artefacts would invent labels)."""

Label = int | tuple[int, int, int]
"""An object's value in a label image: an index, or an (R, G, B) colour."""


def read_label_images(
    folder: str | os.PathLike,
    fps: float,
    *,
    mapping: dict[str, Label | list[Label]] | None = None,
    contact: np.ndarray | str | os.PathLike | None = None,
    camera_K: np.ndarray | None = None,
    action: str | None = None,
    min_area_fraction: float = DEFAULT_MIN_AREA_FRACTION,
) -> Demonstration:
    """Read one label image per frame (files sorted by name).

    Args:
        folder: a folder of label images (:data:`IMAGE_SUFFIXES`): single-channel images
            hold an index per pixel, colour images an (R, G, B) colour per object; 0 / black
            is the background.
        fps: frame rate [1/s].
        mapping: ``{"hand": label, "object": label, "static": label or [labels]}``. None
            detects it by the convention of video segmenters (DAVIS): index 1 is the hand,
            2 the manipulated object, 3, 4, ... static objects; colours are those of the
            DAVIS (PASCAL VOC) palette for these indices.
        contact: (N,) bool contact signal; or the path of a detections CSV
            (:func:`.contact_files.read_detections`); None estimates it from the masks.
            Detections and estimates go through :func:`warpskill.data.contact.filter_contact`.
        camera_K: (3, 3) intrinsics [px]; None for the default of docs/formats.md.
        action: action name, if known.
        min_area_fraction: speck threshold of :func:`warpskill.data.masks.clean_masks` (0, the
            default, keeps every frame).

    Returns:
        The demonstration.

    Raises:
        DemonstrationError: naming the file, for an unreadable image, images of different
            sizes, a colour or index not in the mapping (detected mapping: not in the
            palette), or a mapping without hand and object.
        FileNotFoundError: ``folder`` does not exist or holds no images.
    """
    hand, obj, static = _label_masks(folder, mapping)
    return _demonstration(
        hand, obj, static, fps, contact=contact, camera_K=camera_K, action=action, min_area_fraction=min_area_fraction
    )


def _label_masks(folder, mapping) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """The hand, object and static masks of a folder of label images (see :func:`read_label_images`)."""
    paths = _image_files(folder)
    images = [_read_image(path) for path in paths]
    _check_sizes(paths, images)
    colour = images[0].ndim == 3
    if any((image.ndim == 3) != colour for image in images):
        raise DemonstrationError(f"{folder}: mixes single-channel and colour label images")
    codes = np.stack([_codes(image) for image in images])
    roles = _roles(mapping, colour, np.unique(codes), folder)
    channels = {role: [codes == code for code in role_codes] for role, role_codes in roles.items()}
    stray = ~np.isin(codes, [0, *(code for role_codes in roles.values() for code in role_codes)])
    if stray.any():
        k = int(np.flatnonzero(stray.any(axis=(1, 2)))[0])
        raise DemonstrationError(f"{paths[k]}: label {_describe(int(codes[k][stray[k]][0]), colour)} is in no mapping")
    return channels["hand"][0], channels["object"][0], channels.get("static", [])


def read_mask_folders(
    folder: str | os.PathLike,
    fps: float,
    *,
    contact: np.ndarray | str | os.PathLike | None = None,
    camera_K: np.ndarray | None = None,
    action: str | None = None,
    min_area_fraction: float = DEFAULT_MIN_AREA_FRACTION,
) -> Demonstration:
    """Read one binary image per object and frame.

    ``folder`` holds the sub-folders ``hand/`` and ``object/`` and optionally ``static/``
    or ``static_0/``, ``static_1/``, ... (sorted by name), each with one image per frame
    (sorted by name; any non-zero pixel is set).

    Args:
        folder: the folder of per-object folders.
        fps, contact, camera_K, action, min_area_fraction: as :func:`read_label_images`.

    Raises:
        DemonstrationError: naming the file or folder: unreadable image, different sizes
            or frame counts between the objects.
        FileNotFoundError: no ``hand/`` or ``object/`` folder, or one without images.
    """
    hand, obj, static = _folder_masks(folder)
    return _demonstration(
        hand, obj, static, fps, contact=contact, camera_K=camera_K, action=action, min_area_fraction=min_area_fraction
    )


def _folder_masks(folder) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """The hand, object and static masks of per-object folders (see :func:`read_mask_folders`)."""
    folder = Path(folder)
    static_dirs = sorted(path for path in folder.glob("static*") if path.is_dir())
    stacks = {}
    for sub in [folder / "hand", folder / "object", *static_dirs]:
        paths = _image_files(sub)
        images = [_read_image(path) for path in paths]
        _check_sizes(paths, images)
        stacks[sub] = np.stack([(image.reshape(*image.shape[:2], -1) != 0).any(axis=2) for image in images])
    shapes = {sub.name: stack.shape for sub, stack in stacks.items()}
    if len(set(shapes.values())) > 1:
        raise DemonstrationError(f"{folder}: the object folders disagree in (frames, H, W): {shapes}")
    hand, obj, *static = stacks.values()
    return hand, obj, static


def read_masks(
    folder: str | os.PathLike, *, mapping: dict[str, Label | list[Label]] | None = None
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """The raw masks (not cleaned) of per-object folders (:func:`read_mask_folders`, when
    ``folder/hand/`` exists) or of label images (:func:`read_label_images`).

    Args:
        folder: the masks' folder.
        mapping: as :func:`read_label_images` (label images only).

    Returns:
        (N, H, W) bool hand and object masks and a list of (N, H, W) bool static masks.

    Raises:
        DemonstrationError, FileNotFoundError: as the two readers.
    """
    if (Path(folder) / "hand").is_dir():
        return _folder_masks(folder)
    return _label_masks(folder, mapping)


def read_video_demonstration(
    video: str | os.PathLike,
    masks: str | os.PathLike,
    *,
    fps: float | None = None,
    mapping: dict[str, Label | list[Label]] | None = None,
    contact: np.ndarray | str | os.PathLike | None = None,
    camera_K: np.ndarray | None = None,
    action: str | None = None,
    min_area_fraction: float = DEFAULT_MIN_AREA_FRACTION,
) -> tuple[Demonstration, np.ndarray]:
    """A video file and its masks: per-object folders (:func:`read_mask_folders`, when
    ``masks/hand/`` exists) or label images (:func:`read_label_images`).

    The frames are resized (area average) to the masks' size when they differ, so they can
    be drawn under a reconstruction of the demonstration.

    Args:
        video: a video file OpenCV can read.
        masks: the masks' folder, one mask (set) per video frame.
        fps: frame rate [1/s]; None takes the video's.
        mapping, contact, camera_K, action, min_area_fraction: as :func:`read_label_images`.

    Returns:
        The demonstration and its (N, H, W, 3) uint8 RGB frames.

    Raises:
        DemonstrationError: the video and the masks have different frame counts, the
            video declares no frame rate and ``fps`` is None, or any error of the readers.
    """
    frames, video_fps = read_video(video)
    fps = fps or video_fps
    if not fps:
        raise DemonstrationError(f"{video}: declares no frame rate; pass fps")
    options = dict(contact=contact, camera_K=camera_K, action=action, min_area_fraction=min_area_fraction)
    if (Path(masks) / "hand").is_dir():
        demo = read_mask_folders(masks, fps, **options)
    else:
        demo = read_label_images(masks, fps, mapping=mapping, **options)
    if len(frames) != demo.num_frames:
        raise DemonstrationError(f"{video}: {len(frames)} frames, but {masks} holds masks for {demo.num_frames}")
    h, w = demo.image_size
    if frames.shape[1:3] != (h, w):
        frames = np.stack([cv2.resize(frame, (w, h), interpolation=cv2.INTER_AREA) for frame in frames])
    return demo, frames


def _demonstration(
    hand: np.ndarray,
    obj: np.ndarray,
    static: list[np.ndarray],
    fps: float,
    *,
    contact,
    camera_K,
    action,
    min_area_fraction: float,
) -> Demonstration:
    """Clean the masks, settle the contact signal and build the demonstration."""
    hand, obj = clean_masks(hand, min_area_fraction), clean_masks(obj, min_area_fraction)
    static = [clean_masks(mask, min_area_fraction) for mask in static]
    if contact is None:
        contact = estimate_contact(hand, obj)
    elif isinstance(contact, (str, os.PathLike)):
        contact = estimate_contact(hand, obj, detections=read_detections(contact, len(hand)))
    static_mask = np.stack(static) if static else None
    return Demonstration.from_arrays(hand, obj, contact, fps, static_mask=static_mask, camera_K=camera_K, action=action)


def _image_files(folder: str | os.PathLike) -> list[Path]:
    """The mask images in ``folder``, sorted by name."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: no such folder")
    paths = sorted(path for path in folder.iterdir() if path.suffix.lower() in IMAGE_SUFFIXES)
    if not paths:
        raise FileNotFoundError(f"{folder}: no mask images ({', '.join(IMAGE_SUFFIXES)})")
    return paths


def _read_image(path: Path) -> np.ndarray:
    """A mask image: (H, W) for single-channel files, (H, W, 3) RGB for colour ones."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise DemonstrationError(f"{path}: OpenCV cannot read this image")
    if image.ndim == 3 and image.shape[2] == 4:
        image = image[:, :, :3]
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
    return image


def _check_sizes(paths: list[Path], images: list[np.ndarray]) -> None:
    """Raise unless every image has the first one's height and width."""
    for path, image in zip(paths, images):
        if image.shape[:2] != images[0].shape[:2]:
            raise DemonstrationError(f"{path}: size {image.shape[:2]} differs from {paths[0].name}'s {images[0].shape[:2]}")


def _codes(image: np.ndarray) -> np.ndarray:
    """A label image as (H, W) int64 codes: the index, or R << 16 | G << 8 | B."""
    image = image.astype(np.int64)
    return image[..., 0] << 16 | image[..., 1] << 8 | image[..., 2] if image.ndim == 3 else image


def _code(label: Label, colour: bool) -> int:
    """The code of one mapping value (see :func:`_codes`)."""
    if colour:
        r, g, b = (int(value) for value in label)
        return r << 16 | g << 8 | b
    return int(label)


def _describe(code: int, colour: bool) -> str:
    """A code as the user wrote it: an index, or an (R, G, B) colour."""
    return str((code >> 16, code >> 8 & 255, code & 255)) if colour else str(code)


def _roles(mapping: dict | None, colour: bool, present: np.ndarray, folder) -> dict[str, list[int]]:
    """Role ("hand", "object", "static") -> the codes of its labels, from ``mapping`` or,
    when None, by the DAVIS convention (index 1 hand, 2 object, 3, 4, ... the static
    objects that are present; colours from :func:`davis_palette`)."""
    if mapping is None:
        indices = range(256)
        codes = [_code(tuple(rgb), True) for rgb in davis_palette(256)] if colour else list(indices)
        static = [code for code in codes[3:] if code in present]
        return {"hand": [codes[1]], "object": [codes[2]], "static": static}
    unknown = set(mapping) - {"hand", "object", "static"}
    missing = {"hand", "object"} - set(mapping)
    if unknown or missing:
        raise DemonstrationError(
            f"{folder}: mapping needs the keys hand, object and optionally static; "
            f"missing {sorted(missing)}, unknown {sorted(unknown)}"
        )
    roles = {}
    for role, value in mapping.items():
        values = value if role == "static" and isinstance(value, list) else [value]
        for item in values:
            is_colour = np.ndim(item) == 1 and len(item) == 3
            is_index = isinstance(item, (int, np.integer)) and not isinstance(item, bool)
            if (colour and not is_colour) or (not colour and not is_index):
                kind = "(R, G, B) colours" if colour else "integer indices"
                raise DemonstrationError(f"{folder}: the images need {kind} in the mapping, got {role}: {item!r}")
        roles[role] = [_code(item, colour) for item in values]
    return roles


def davis_palette(count: int) -> np.ndarray:
    """The DAVIS / PASCAL VOC colour palette that video segmenters write label PNGs with.

    Returns:
        (count, 3) uint8 RGB; row i is the colour of label index i.
    """
    palette = np.zeros((count, 3), dtype=np.uint8)
    for index in range(count):
        value = index
        for bit in range(8):
            for channel in range(3):
                palette[index, channel] |= ((value >> channel) & 1) << (7 - bit)
            value >>= 3
    return palette
