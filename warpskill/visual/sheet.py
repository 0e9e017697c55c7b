"""The contact sheet: what the optimiser will see of a demonstration, on one PNG.

:func:`contact_sheet` draws the masks over sampled frames (each role in its colour of the
palette, :mod:`warpskill.media`), each frame's contact flag, the found hand's landmarks
where given, the outline proposed on one frame where given (dashed, on that frame's tile),
and a strip of the contact signal of every frame. OpenCV only; the command
line hands it what :func:`warpskill.data.read_recording` read.
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.vocabulary import HAND, OBJECT, STATIC
from warpskill.media import HAND_COLOR, HAND_HELD_COLOR, OBJECT_COLOR, STATIC_COLOR

SHEET_TILES = 12
"""Frames drawn on the contact sheet (at most; evenly spaced, first and last included)."""

ROLE_COLORS = {HAND: HAND_COLOR, OBJECT: OBJECT_COLOR, STATIC: STATIC_COLOR}
"""RGB of each role's masks: the palette's."""

CONTACT_COLOR = HAND_HELD_COLOR
"""RGB of a frame in contact: the palette's hand holding the object."""

NO_CONTACT_COLOR = (70, 70, 70)
"""RGB of a drawn frame's header without contact."""

HAND_BONES = ((0, 1), (1, 2), (2, 3), (3, 4), (0, 5), (5, 6), (6, 7), (7, 8), (5, 9), (9, 10), (10, 11),
              (11, 12), (9, 13), (13, 14), (14, 15), (15, 16), (13, 17), (0, 17), (17, 18), (18, 19), (19, 20))
"""Pairs of hand landmarks joined when the found hand is drawn (MediaPipe's 21-point hand)."""


def contact_sheet(
    demo: Demonstration, frames: np.ndarray | None, path: str | os.PathLike, landmarks: np.ndarray | None = None,
    *, outline: tuple[int, dict[str, np.ndarray]] | None = None,
) -> Path:
    """Draw the masks over sampled frames with each frame's contact flag, and a strip of the
    contact signal of every frame; write it as a PNG (OpenCV).

    Args:
        demo: the demonstration.
        frames: its (N, H, W, 3) uint8 RGB video frames, or None to draw on grey.
        path: the PNG to write.
        landmarks: (N, 21, 2) the found hand's landmarks [px] (NaN rows where none), drawn
            as a skeleton; None draws none.
        outline: the outline proposed from the video, (frame, label (``object``,
            ``static_0``, ...) -> (K, 2) polygon [px]), drawn dashed in white on that frame's
            tile (which is then among the drawn frames), its header saying so; None draws none.

    Returns:
        ``path``.

    Raises:
        ValueError: ``frames`` disagree with the demonstration's frame count or size.
    """
    n, (h, w) = demo.num_frames, demo.image_size
    if frames is None:
        frames = np.full((n, h, w, 3), 96, dtype=np.uint8)
    frames = np.asarray(frames)
    if frames.shape != (n, h, w, 3):
        raise ValueError(f"frames: expected shape {(n, h, w, 3)} for the demonstration, got {frames.shape}")
    scale = float(np.clip(240.0 / w, 1.0, None)) if w < 240 else min(1.0, 320.0 / w)
    tile_w, tile_h = int(round(w * scale)), int(round(h * scale))
    header, gap = 18, 4
    picks = np.unique(np.round(np.linspace(0, n - 1, min(n, SHEET_TILES))).astype(int))
    if outline is not None and outline[0] not in picks:
        picks = np.sort(np.append(np.delete(picks, np.argmin(np.abs(picks - outline[0]))), outline[0]))
    columns = min(4, len(picks))
    rows = -(-len(picks) // columns)
    width = columns * (tile_w + gap) + gap
    strip_h = 44
    sheet = np.full((rows * (tile_h + header + gap) + gap + strip_h, width, 3), 255, dtype=np.uint8)
    for index, k in enumerate(picks):
        tile = _overlay(demo, frames, int(k))
        if landmarks is not None:
            _skeleton(tile, landmarks[k])
        outlined = outline is not None and outline[0] == k
        if outlined:
            _dashed(tile, outline[1].values())
        tile = cv2.resize(tile, (tile_w, tile_h), interpolation=cv2.INTER_NEAREST if scale > 1 else cv2.INTER_AREA)
        y = gap + (index // columns) * (tile_h + header + gap)
        x = gap + (index % columns) * (tile_w + gap)
        on = bool(demo.contact[k])
        sheet[y : y + header, x : x + tile_w] = CONTACT_COLOR if on else NO_CONTACT_COLOR
        text = f"frame {k}  " + ("contact" if on else "no contact") + ("  outline" if outlined else "")
        cv2.putText(sheet, text, (x + 4, y + header - 5), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (255, 255, 255), 1, cv2.LINE_AA)
        sheet[y + header : y + header + tile_h, x : x + tile_w] = tile
    _strip(sheet, demo, picks, sheet.shape[0] - strip_h, gap)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR)):
        raise OSError(f"{path}: OpenCV could not write the contact sheet")
    return path


def _overlay(demo: Demonstration, frames: np.ndarray, k: int) -> np.ndarray:
    """Frame ``k`` with each mask tinted in its role's colour and outlined."""
    tile = frames[k].astype(np.float32)
    layers = [(STATIC, mask[k]) for mask in demo.static_mask] + [(OBJECT, demo.object_mask[k]), (HAND, demo.hand_mask[k])]
    for role, mask in layers:
        tile[mask] = 0.55 * tile[mask] + 0.45 * np.array(ROLE_COLORS[role], dtype=np.float32)
    tile = tile.astype(np.uint8)
    for role, mask in layers:
        contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        cv2.drawContours(tile, contours, -1, ROLE_COLORS[role], 1)
    return tile


DASH_PX = 4
"""Length [px] of the dashes and gaps of a proposed outline's polygons on the sheet."""


def _dashed(tile: np.ndarray, polygons) -> None:
    """Each polygon (K, 2) [px] drawn dashed in white on ``tile`` in place."""
    for points in polygons:
        closed = np.vstack([points, points[:1]]) - 0.5  # pixel centres at integers
        for a, b in zip(closed[:-1], closed[1:]):
            length = max(float(np.linalg.norm(b - a)), 1e-9)
            for start in np.arange(0.0, length, 2 * DASH_PX):
                dash = [a + (b - a) * at / length for at in (start, min(start + DASH_PX, length))]
                p, q = (tuple(int(v) for v in np.round(end * 16)) for end in dash)
                cv2.line(tile, p, q, (255, 255, 255), 1, cv2.LINE_AA, shift=4)


def _skeleton(tile: np.ndarray, points: np.ndarray) -> None:
    """The found hand's landmarks (21, 2) [px] drawn on ``tile`` in place (nothing for NaN)."""
    if not np.isfinite(points).all():
        return
    pixel = np.round(points * 16 - 8).astype(np.int32)
    for a, b in HAND_BONES:
        cv2.line(tile, tuple(pixel[a]), tuple(pixel[b]), (255, 255, 255), 1, cv2.LINE_AA, shift=4)
    for point in pixel:
        cv2.circle(tile, tuple(point), 2 * 16, (255, 230, 0), -1, cv2.LINE_AA, shift=4)


def _strip(sheet: np.ndarray, demo: Demonstration, picks: np.ndarray, top: int, gap: int) -> None:
    """The contact signal of every frame along the bottom of ``sheet``, the drawn frames ticked, and the legend."""
    n, width = demo.num_frames, sheet.shape[1] - 2 * gap
    edges = np.round(np.linspace(gap, gap + width, n + 1)).astype(int)
    for k in range(n):
        colour = CONTACT_COLOR if demo.contact[k] else (215, 215, 215)
        sheet[top + 4 : top + 16, edges[k] : max(edges[k + 1] - 1, edges[k] + 1)] = colour
    for k in picks:
        sheet[top + 17 : top + 21, edges[k] : max(edges[k + 1] - 1, edges[k] + 1)] = 0
    x = gap
    for label, colour in (*ROLE_COLORS.items(), ("contact", CONTACT_COLOR)):
        sheet[top + 27 : top + 39, x : x + 12] = colour
        cv2.putText(sheet, label, (x + 16, top + 38), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
        x += 22 + 8 * len(label)
    on = np.flatnonzero(demo.contact)
    summary = f"{n} frames, {demo.fps:g} fps, contact in {len(on)}"
    cv2.putText(sheet, summary, (x + 10, top + 38), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
