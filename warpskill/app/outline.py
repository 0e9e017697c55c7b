"""The outline being drawn on the page: the polygon file of docs/formats.md as text, boxes
from two clicks, its picture on the frame, and the proposal that fills it.

The page holds the outline as the polygon file's JSON text (``frame``, ``hand``, ``object``,
``static``, ``object_noun``), so what a user sees and edits is what ``warpskill run
--polygons`` reads; a draft may lack polygons (the run then says which is missing).
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from warpskill.contract.vocabulary import HAND, OBJECT, static_role
from warpskill.data import propose_outline, write_outline
from warpskill.media import HAND_COLOR, OBJECT_COLOR, STATIC_COLOR

__all__ = ["ROLES", "draft", "draw_outline", "outline_text", "parse_outline", "propose", "remove_role", "shown_scale",
           "shown_to_frame", "with_box"]

ROLES = (OBJECT, HAND, static_role(0), static_role(1), static_role(2))
"""The polygons a user draws: the object, the hand (optional: left out, it is found) and up to three static objects."""

FILL_ALPHA = 0.3
"""Opacity of a polygon's fill on the frame."""

SHOWN_HEIGHT_PX = 360
"""A small frame is shown enlarged by a whole factor to at least this height [px], so a click picks one pixel."""


def draft(frame: int) -> dict:
    """An outline with no polygon yet, on ``frame``."""
    return {"frame": int(frame), "static": []}


def parse_outline(text: str) -> dict:
    """The outline in ``text`` (the polygon file's JSON; empty: an empty draft on frame 0).

    Raises:
        ValueError: not JSON, or not an object with a 0-based ``frame``.
    """
    if not text.strip():
        return draft(0)
    try:
        outline = json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(f"the outline is not valid JSON ({error})") from None
    frame = outline.get("frame") if isinstance(outline, dict) else None
    if isinstance(frame, bool) or not isinstance(frame, int) or frame < 0:
        raise ValueError("the outline needs \"frame\": the 0-based index of the frame it is drawn on")
    return outline


def outline_text(outline: dict) -> str:
    """The polygon file's JSON, one key per line, its points rounded to 0.1 px."""
    def rounded(value):
        if isinstance(value, float):
            return round(value, 1)
        return [rounded(v) for v in value] if isinstance(value, list) else value

    lines = [f"  {json.dumps(key)}: {json.dumps(rounded(value))}" for key, value in outline.items()]
    return "{\n" + ",\n".join(lines) + "\n}"


def _static_index(role: str) -> int | None:
    return int(role.split("_")[1]) if role.startswith("static_") else None


def with_box(outline: dict, role: str, corner: tuple[float, float], other: tuple[float, float]) -> dict:
    """``outline`` with ``role``'s polygon the box spanned by two corners [px]; a static
    role past the last static object adds one."""
    (x0, x1), (y0, y1) = sorted((corner[0], other[0])), sorted((corner[1], other[1]))
    box = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
    changed = {**outline, "static": list(outline.get("static", []))}
    index = _static_index(role)
    if index is None:
        changed[role] = box
    elif index < len(changed["static"]):
        changed["static"][index] = box
    else:
        changed["static"].append(box)
    return changed


def remove_role(outline: dict, role: str) -> dict:
    """``outline`` without ``role``'s polygon."""
    changed = {key: value for key, value in outline.items() if key != role}
    index = _static_index(role)
    if index is not None:
        changed["static"] = [p for k, p in enumerate(outline.get("static", [])) if k != index]
    return changed


def _polygons(outline: dict) -> list[tuple[tuple[int, int, int], list]]:
    """(colour, points) of each polygon in ``outline``, back to front."""
    drawn = [(STATIC_COLOR, points) for points in outline.get("static", [])]
    drawn += [(color, outline[key]) for key, color in ((OBJECT, OBJECT_COLOR), (HAND, HAND_COLOR)) if key in outline]
    return drawn


def shown_scale(image_size: tuple[int, int]) -> int:
    """The whole factor a frame of (H, W) ``image_size`` is enlarged by on the page."""
    return max(1, -(-SHOWN_HEIGHT_PX // image_size[0]))


def shown_to_frame(index: tuple[float, float], image_size: tuple[int, int]) -> tuple[float, float]:
    """A pixel of the enlarged frame (x, y) to the centre of the frame's pixel under it [px]."""
    scale = shown_scale(image_size)
    return float(index[0] // scale) + 0.5, float(index[1] // scale) + 0.5


def draw_outline(frame: np.ndarray, outline: dict, pending: tuple[float, float] | None = None) -> np.ndarray:
    """(s H, s W, 3) uint8: ``frame`` enlarged by :func:`shown_scale` s, with the outline's polygons
    filled and edged in the pictures' colours, and ``pending`` (a box's first corner [px]) as a cross."""
    scale = shown_scale(frame.shape[:2])
    picture = cv2.resize(frame, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    for color, points in _polygons(outline):
        try:
            pixels = np.round(np.asarray(points, dtype=float) * scale * 16 - 8).astype(np.int32)
        except (TypeError, ValueError):
            continue  # a half-typed polygon: drawn once it is whole
        if pixels.ndim != 2 or pixels.shape[1] != 2 or len(pixels) < 2:
            continue
        filled = picture.copy()
        cv2.fillPoly(filled, [pixels], color, shift=4)
        picture = cv2.addWeighted(filled, FILL_ALPHA, picture, 1.0 - FILL_ALPHA, 0.0)
        cv2.polylines(picture, [pixels], True, color, 1 + (scale > 1), cv2.LINE_AA, shift=4)
    if pending is not None:
        x, y = (int(v * scale) for v in pending)
        cv2.drawMarker(picture, (x, y), (255, 255, 255), cv2.MARKER_CROSS, 4 * scale + 1, 1)
    return picture


def propose(frames: np.ndarray, action: str, fps: float, path: Path, *, object_noun: str | None = None,
            static_noun: str | None = None) -> dict:
    """The outline proposed for the clip (:func:`warpskill.data.footage.outline_proposal.propose_outline`),
    written to ``path`` as the polygon file and returned.

    Raises:
        OutlineUnsure: the clip does not say what to outline (its line says what; its picture shows what was seen).
        ImportError: MediaPipe, which finds the hand, is not installed (extra ``video``).
    """
    proposal = propose_outline(frames, action, fps=fps, object_noun=object_noun, static_noun=static_noun)
    write_outline(proposal, path)
    return json.loads(path.read_text())
