"""Masks for a whole video from polygons drawn on one frame.

The user outlines the hand and the objects on one frame (:func:`read_polygons`: the polygon
file of ``docs/formats.md`` or a LabelMe file, :func:`read_labelme`); the masks
are carried to the other frames, forward and backward from that frame, one frame at a
time: dense optical flow (OpenCV's Farneback) between consecutive frames, inside the
visible part of each mask and away from its edge, fits a similarity transform (RANSAC)
that moves the mask (on small videos the flow is computed on frames enlarged to
:data:`FLOW_MIN_SIDE` px, so that its window does not blur a small object with its
surroundings); a refinement step cleans it (morphological opening and closing,
holes filled, the largest blob kept). Each label keeps its whole shape, so a part hidden
for a while (the object behind the hand) comes back; labels given first are in front
(give the hand first, then the manipulated object, then static objects). Masks live on a
canvas larger than the image, so parts that leave the view come back; the hand's mask,
where it touches the image border on the annotated frame, is extended beyond it (the arm
goes on out of view), so the arm follows the hand into the image.

Limits, honestly: errors accumulate frame by frame, so masks drift on long videos; flow
follows texture, so uniform objects, motion blur and large motions (more than about a
tenth of the image per frame) lose parts of the mask; a mask moves as a whole (a
similarity per frame), so deforming shapes (fingers closing) are followed only roughly; an
object that is fully occluded stops (no flow to follow) and one mostly hidden lags; a part
that is hidden on the annotated frame is never recovered; thin structures (a fork's prongs) erode away. For real work a learned
propagator (STCN, XMem) is much better: its per-frame label images read with
:func:`warpskill.data.readers.read_label_images`.
"""

from __future__ import annotations

import json
import os
import re
from typing import NamedTuple

import cv2
import numpy as np

from warpskill.contract.demonstration import DemonstrationError
from warpskill.data.masks import largest_component

EDGE_PX = 3
"""Flow this close to a mask's edge [px] is not used to move it."""

MIN_POINTS = 6
"""Fewest visible mask pixels whose flow moves a mask; a mask seen less vanishes."""

FLOW_MIN_SIDE = 240
"""Optical flow runs on frames enlarged (bicubic) until their shorter side has this many px."""

EXTENDED_LABELS = ("hand",)
"""Labels whose mask is extended beyond the image border it touches on the annotated frame."""


POLYGON_KEYS = ("frame", "hand", "object", "static", "object_noun")
"""Keys of the polygon file (``hand`` left out: the hand is found in every frame;
``static`` left out: no static objects; ``object_noun`` optional)."""


class Outline(NamedTuple):
    """The polygons drawn on one frame, as masks.

    Attributes:
        frame: the annotated frame's 0-based index.
        masks: label -> (H, W) bool mask in front-to-back order: ``hand`` (when outlined),
            ``object``, ``static_0``, ``static_1``, ...
        object_noun: what the manipulated object is (``"marker"``), or None.
    """

    frame: int
    masks: dict[str, np.ndarray]
    object_noun: str | None = None

BORDER_SLACK_PX = 1.0
"""How far [px] a polygon's point may lie outside the image (a click on its edge)."""


def read_polygons(path: str | os.PathLike, image_size: tuple[int, int], *, frame: int | None = None) -> Outline:
    """Read the polygons drawn on one frame, as masks.

    The file is JSON, either the polygon file of ``docs/formats.md``::

        {"frame": k, "hand": [[x, y], ...], "object": [[x, y], ...], "static": [[[x, y], ...], ...],
         "object_noun": "marker"}

    with k the 0-based frame index, one polygon for the hand (optional: without it the
    hand is found in every frame), one for the manipulated object, a list of polygons, one
    per static object (possibly empty), and optionally the object's noun, in pixel
    coordinates of the video's frames (continuous, (0, 0) the top-left corner of the
    image); or a LabelMe file (detected by its ``shapes`` key; :func:`read_labelme`).

    Args:
        path: the JSON file.
        image_size: (H, W) of the video frames [px].
        frame: the annotated frame's 0-based index, overriding the file's (LabelMe files
            without digits in their image name need it).

    Returns:
        The outline: the frame index, the masks and the object's noun.

    Raises:
        DemonstrationError: naming the file and the key, for a malformed file, a polygon
            of fewer than 3 points, a point outside the image, a polygon enclosing less
            than a pixel, or (LabelMe) an image of another size.
        FileNotFoundError: ``path`` does not exist.
    """
    data = _read_json(path)
    if isinstance(data, dict) and "shapes" in data:
        polygons = _labelme_polygons(data, path, frame, image_size)
    else:
        polygons = _check_polygons(data, path)
        if frame is not None:
            polygons["frame"] = _frame_index(frame, path)
    height, width = image_size
    masks = {}
    named = [("hand", polygons["hand"])] * (polygons["hand"] is not None) + [("object", polygons["object"])]
    named += [(f"static_{k}", points) for k, points in enumerate(polygons["static"])]
    for label, points in named:
        key = label if label in ("hand", "object") else f"static[{label.split('_')[1]}]"
        points = np.asarray(points, dtype=float)
        outside = (points < -BORDER_SLACK_PX).any(axis=1) | (points > [width + BORDER_SLACK_PX, height + BORDER_SLACK_PX]).any(axis=1)
        if outside.any():
            x, y = points[np.flatnonzero(outside)[0]]
            raise DemonstrationError(
                f"{path}: {key}: point [{x:g}, {y:g}] lies outside the {width} x {height} (W x H) video frames"
            )
        x, y = points.T
        area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
        if area < 1.0:
            raise DemonstrationError(f"{path}: {key}: the polygon encloses {area:g} px^2, less than one pixel")
        mask = np.zeros(image_size, dtype=np.uint8)
        cv2.fillPoly(mask, [np.round((points - 0.5) * 16).astype(np.int32)], 1, shift=4)
        masks[label] = mask.astype(bool)
    return Outline(polygons["frame"], masks, polygons.get("object_noun"))


def read_labelme(path: str | os.PathLike, *, frame: int | None = None) -> dict:
    """Read a LabelMe annotation of one frame as the polygon file's structure.

    LabelMe writes ``{"shapes": [{"label": ..., "points": [[x, y], ...], "shape_type":
    "polygon"}, ...], "imagePath": ..., "imageHeight": ..., "imageWidth": ...}``. Shapes
    labelled ``hand`` (at most one; none: the hand is found) and ``object`` (one) are the
    hand and the manipulated object;
    every shape whose label starts with ``static`` is one static object (ordered by label,
    then as in the file). ``polygon`` and ``rectangle`` shapes are read.

    Args:
        path: the LabelMe JSON file.
        frame: the annotated frame's 0-based index; None reads it from the digits of the
            ``imagePath`` file name (``frame_0012.png`` -> 12).

    Returns:
        ``{"frame": k, "hand": [[x, y], ...] or None, "object": [[x, y], ...], "static": [[[x, y], ...], ...]}``.

    Raises:
        DemonstrationError: naming the file and the shape, for a malformed file, an
            unknown label or shape type, a label given twice, no hand or object, or no
            frame index.
        FileNotFoundError: ``path`` does not exist.
    """
    return _labelme_polygons(_read_json(path), path, frame, None)


def _read_json(path: str | os.PathLike):
    """The JSON document in ``path``."""
    with open(path) as handle:
        try:
            return json.load(handle)
        except json.JSONDecodeError as exc:
            raise DemonstrationError(f"{path}: not valid JSON ({exc})") from None


def _frame_index(value, path) -> int:
    """``value`` as a 0-based frame index."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise DemonstrationError(f"{path}: frame: expected a 0-based frame index >= 0, got {value!r}")
    return int(value)


def _points(value, path, key: str) -> list[list[float]]:
    """One polygon: at least 3 finite [x, y] pairs."""
    try:
        points = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        points = np.zeros((0,))
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 3 or not np.isfinite(points).all():
        raise DemonstrationError(f"{path}: {key}: expected a polygon of at least 3 finite [x, y] points")
    return points.tolist()


def _check_polygons(data, path) -> dict:
    """The polygon file's structure, checked."""
    if not isinstance(data, dict):
        raise DemonstrationError(f"{path}: expected an object with the keys {', '.join(POLYGON_KEYS)}")
    unknown = sorted(set(data) - set(POLYGON_KEYS))
    missing = [key for key in ("frame", "object") if key not in data]
    if unknown or missing:
        problems = [f"missing {', '.join(missing)}"] * bool(missing) + [f"unknown {', '.join(unknown)}"] * bool(unknown)
        raise DemonstrationError(
            f"{path}: expected the keys frame, object and optionally hand, static, object_noun; {'; '.join(problems)}"
        )
    static = data.get("static", [])
    if not isinstance(static, list):
        raise DemonstrationError(f"{path}: static: expected a list of polygons, one per static object")
    noun = data.get("object_noun")
    if noun is not None and (not isinstance(noun, str) or not noun.strip()):
        raise DemonstrationError(f"{path}: object_noun: expected a non-empty string, got {noun!r}")
    return {
        "frame": _frame_index(data["frame"], path),
        "hand": _points(data["hand"], path, "hand") if "hand" in data else None,
        "object_noun": noun.strip() if noun else None,
        "object": _points(data["object"], path, "object"),
        "static": [_points(points, path, f"static[{k}]") for k, points in enumerate(static)],
    }


def _labelme_polygons(data, path, frame: int | None, image_size: tuple[int, int] | None) -> dict:
    """A LabelMe document as the polygon file's structure (see :func:`read_labelme`);
    checks the image size against ``image_size`` (H, W) when given."""
    if not isinstance(data, dict) or not isinstance(data.get("shapes"), list):
        raise DemonstrationError(f"{path}: shapes: expected a LabelMe list of shapes")
    if image_size is not None and "imageHeight" in data and "imageWidth" in data:
        if (data["imageHeight"], data["imageWidth"]) != tuple(image_size):
            raise DemonstrationError(
                f"{path}: drawn on a {data['imageWidth']} x {data['imageHeight']} (W x H) image, "
                f"the video's frames are {image_size[1]} x {image_size[0]}"
            )
    found: dict[str, list] = {"hand": [], "object": [], "static": []}
    for index, shape in enumerate(data["shapes"]):
        where = f"shapes[{index}]"
        label = shape.get("label") if isinstance(shape, dict) else None
        role = label if label in ("hand", "object") else "static" if isinstance(label, str) and label.startswith("static") else None
        if role is None:
            raise DemonstrationError(f"{path}: {where}: label {label!r}: expected hand, object or static*")
        kind = shape.get("shape_type") or "polygon"
        points = shape.get("points")
        if kind == "rectangle":
            try:
                (x0, y0), (x1, y1) = points
            except (TypeError, ValueError):
                raise DemonstrationError(f"{path}: {where}: a rectangle needs 2 corner points") from None
            points = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
        elif kind != "polygon":
            raise DemonstrationError(f"{path}: {where}: shape_type {kind!r}: expected polygon or rectangle")
        found[role].append((label, _points(points, path, f"{where} ({label})")))
    for role in ("hand", "object"):
        if len(found[role]) != 1 and not (role == "hand" and not found[role]):
            problem = "no shape" if not found[role] else f"{len(found[role])} shapes"
            raise DemonstrationError(f"{path}: {problem} labelled {role!r}: expected exactly one polygon")
    if frame is None:
        name = os.path.basename(str(data.get("imagePath") or ""))
        digits = re.findall(r"\d+", os.path.splitext(name)[0])
        if not digits:
            raise DemonstrationError(
                f"{path}: no frame index: imagePath {data.get('imagePath')!r} has no digits; give the frame (--frame)"
            )
        frame = int(digits[-1])
    statics = sorted(found["static"], key=lambda item: item[0])  # stable: same labels keep the file's order
    return {
        "frame": _frame_index(frame, path),
        "hand": found["hand"][0][1] if found["hand"] else None,
        "object": found["object"][0][1],
        "static": [points for _, points in statics],
    }


def propagate_masks(
    frames: np.ndarray, key_frame: int, key_masks: dict[str, np.ndarray], *, refine: bool = True
) -> dict[str, np.ndarray]:
    """Carry masks from ``key_frame`` to every frame of the video (see the module docstring).

    Args:
        frames: (N, H, W, 3) uint8 RGB video frames.
        key_frame: index of the annotated frame.
        key_masks: label -> (H, W) bool mask on the annotated frame.
        refine: apply the refinement step after each warp.

    Returns:
        label -> (N, H, W) bool visible masks; each pixel belongs to one label at most,
        the first in ``key_masks``' order that covers it.

    Raises:
        ValueError: frames that are not (N, H, W, 3) uint8, ``key_frame`` out of range, or a
            mask of another size.
    """
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[3] != 3 or frames.dtype != np.uint8:
        raise ValueError(f"frames: expected (N, H, W, 3) uint8, got {frames.dtype} of shape {frames.shape}")
    n, h, w = frames.shape[:3]
    if not 0 <= key_frame < n:
        raise ValueError(f"key_frame: {key_frame} outside 0..{n - 1}")
    labels = list(key_masks)
    for label in labels:
        if np.shape(key_masks[label]) != (h, w):
            raise ValueError(f"key_masks[{label!r}]: expected shape {(h, w)}, got {np.shape(key_masks[label])}")
    scale = max(1.0, FLOW_MIN_SIDE / min(h, w))
    gray = [cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY) for frame in frames]
    if scale > 1:
        gray = [cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC) for image in gray]
    key = np.stack([np.asarray(key_masks[label], dtype=bool) for label in labels])
    pad = max(h, w) // 2  # the canvas around the image on which whole masks live
    canvas = np.stack([
        cv2.copyMakeBorder(mask.astype(np.uint8), pad, pad, pad, pad,
                           cv2.BORDER_REPLICATE if label in EXTENDED_LABELS else cv2.BORDER_CONSTANT, value=0)
        for label, mask in zip(labels, key)
    ]).astype(bool)
    out = np.zeros((len(labels), n, h, w), dtype=bool)
    out[:, key_frame] = key
    for step in (1, -1):
        whole = canvas  # each label's mask including its parts hidden behind earlier labels or out of view
        for k in range(key_frame + step, n if step > 0 else -1, step):
            flow = cv2.calcOpticalFlowFarneback(gray[k - step], gray[k], None, 0.5, 3, 15, 3, 5, 1.2, 0)
            whole = np.stack([_moved(mask, seen, flow, scale, pad) for mask, seen in zip(whole, out[:, k - step])])
            if refine:
                whole = np.stack([_refine(mask) for mask in whole])
            out[:, k] = _in_front(whole)[:, pad : pad + h, pad : pad + w]
    return dict(zip(labels, out))


def _in_front(whole: np.ndarray) -> np.ndarray:
    """(L, H, W) whole masks -> visible masks: each pixel to the first label covering it."""
    covered = np.cumsum(whole, axis=0) > 0
    visible = whole.copy()
    visible[1:] &= ~covered[:-1]
    return visible


def _moved(whole: np.ndarray, visible: np.ndarray, flow: np.ndarray, scale: float, pad: int) -> np.ndarray:
    """A whole mask on the canvas (the image with ``pad`` px all round) moved to the next
    frame by the similarity transform (rotation, scale, shift) fitted with RANSAC to the
    forward ``flow`` (computed on frames enlarged by ``scale``) inside its (H, W) visible
    part, away from the edge (flow there mixes the object with what surrounds it)."""
    image = visible.astype(np.uint8)
    interior = cv2.erode(image, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (EDGE_PX * 2 + 1,) * 2))
    ys, xs = np.nonzero(interior if interior.sum() >= MIN_POINTS else image)
    if len(xs) < MIN_POINTS:
        return np.zeros(whole.shape, dtype=bool)
    source = np.stack([xs, ys], axis=1).astype(np.float32)
    fy = np.clip(np.round((ys + 0.5) * scale - 0.5), 0, flow.shape[0] - 1).astype(int)
    fx = np.clip(np.round((xs + 0.5) * scale - 0.5), 0, flow.shape[1] - 1).astype(int)
    target = source + flow[fy, fx] / scale
    transform, _ = cv2.estimateAffinePartial2D(source, target, method=cv2.RANSAC, ransacReprojThreshold=1.0)
    if transform is None:
        transform = np.hstack([np.eye(2), np.median(target - source, axis=0)[:, None]]).astype(np.float32)
    linear = transform[:, :2]
    on_canvas = np.hstack([linear, (transform[:, 2] + pad - linear @ np.array([pad, pad]))[:, None]])
    height, width = whole.shape
    moved = cv2.warpAffine(whole.astype(np.float32), on_canvas.astype(np.float32), (width, height), flags=cv2.INTER_LINEAR)
    return moved >= 0.5


def _refine(mask: np.ndarray) -> np.ndarray:
    """Opening and closing (3 x 3), holes filled, the largest blob kept."""
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    image = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, kernel)
    image = cv2.morphologyEx(image, cv2.MORPH_CLOSE, kernel)
    contours, _ = cv2.findContours(image, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    filled = np.zeros_like(image)
    cv2.drawContours(filled, contours, -1, 1, thickness=cv2.FILLED)
    return largest_component(filled.astype(bool)[None])[0]
