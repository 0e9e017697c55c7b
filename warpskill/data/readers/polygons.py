"""The outline a user draws on one frame, read as masks: the polygon file or a LabelMe file.

:func:`read_polygons` reads the polygon file of ``docs/formats.md`` (or a LabelMe file,
:func:`read_labelme`) into an :class:`Outline`: the annotated frame, one mask per role
(``hand`` when outlined, ``object``, ``static_0``, ...; :mod:`warpskill.contract.vocabulary`)
and the object's noun. The footage path carries it through the video
(:mod:`warpskill.data.footage`).
"""

from __future__ import annotations

import json
import os
import re
from typing import NamedTuple

import cv2
import numpy as np

from warpskill.contract.demonstration import DemonstrationError
from warpskill.contract.vocabulary import HAND, OBJECT, static_role

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
    named = [(HAND, polygons["hand"])] * (polygons["hand"] is not None) + [(OBJECT, polygons["object"])]
    named += [(static_role(k), points) for k, points in enumerate(polygons["static"])]
    for label, points in named:
        key = label if label in (HAND, OBJECT) else f"static[{label.split('_')[1]}]"
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
        masks[label] = polygon_mask(points, image_size)
    return Outline(polygons["frame"], masks, polygons.get("object_noun"))


def polygon_mask(points: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """(H, W) bool: the pixels whose centres the polygon ``points`` (K, 2) [px, continuous,
    (0, 0) the image's top-left corner] encloses, as the polygon file is read."""
    mask = np.zeros(image_size, dtype=np.uint8)
    cv2.fillPoly(mask, [np.round((np.asarray(points, dtype=float) - 0.5) * 16).astype(np.int32)], 1, shift=4)
    return mask.astype(bool)


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
