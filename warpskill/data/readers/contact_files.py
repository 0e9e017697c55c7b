"""Contact files: a detector's per-frame detections, or the contact signal itself.

:func:`read_detections` reads a hand-object contact detector's CSV (``frame``,
``in_contact``, optionally ``score``) as raw detections for the paper's filter
(:func:`warpskill.data.contact.filter_contact`); :func:`read_contact` reads a contact CSV
(``contact``, optionally ``frame``) as the signal, used as given. Every error names the
file and line (:class:`~warpskill.contract.DemonstrationError`).
"""

from __future__ import annotations

import csv
import math
import os

import numpy as np

from warpskill.contract.demonstration import DemonstrationError
from warpskill.data.contact import IN_CONTACT, NO_CONTACT, UNKNOWN


def read_detections(path: str | os.PathLike, num_frames: int, *, min_score: float = 0.5) -> np.ndarray:
    """Read a hand-object contact detections CSV.

    The file has a header row with the columns ``frame`` (0-based index into the masks),
    ``in_contact`` (0/1, or true/false) and optionally ``score`` (the detector's confidence
    in [0, 1]). A frame absent from the file, or detected with ``score < min_score``, is
    :data:`UNKNOWN`.

    Args:
        path: the CSV file.
        num_frames: N, the number of frames of the masks.
        min_score: detections below this score count as no detection.

    Returns:
        (N,) int8 in {UNKNOWN, NO_CONTACT, IN_CONTACT}.

    Raises:
        DemonstrationError: (a ValueError) naming the file and line, for text that is not
            UTF-8 CSV, a missing column, a frame out of range or repeated, or a value that is
            not a number / boolean (a score that is not finite).
        FileNotFoundError: ``path`` does not exist.
    """
    detections = np.full(num_frames, UNKNOWN, dtype=np.int8)
    seen = set()
    with open(path, newline="", encoding="utf-8-sig") as handle:
        reader = csv.DictReader(handle)
        try:
            missing = {"frame", "in_contact"} - set(reader.fieldnames or ())
            if missing:
                raise DemonstrationError(
                    f"{path}: missing column(s) {', '.join(sorted(missing))}; expected frame,in_contact[,score]"
                )
            for row in reader:
                where = f"{path}, line {reader.line_num}"
                frame = _parse(where, "frame", row["frame"], int)
                if not 0 <= frame < num_frames:
                    raise DemonstrationError(f"{where}: frame {frame} outside 0..{num_frames - 1}")
                if frame in seen:
                    raise DemonstrationError(f"{where}: frame {frame} listed twice")
                seen.add(frame)
                if row.get("score") not in (None, ""):
                    score = _parse(where, "score", row["score"], float)
                    if not math.isfinite(score):
                        raise DemonstrationError(f"{where}: column score: expected a finite number, got {row['score']!r}")
                    if score < min_score:
                        continue
                detections[frame] = IN_CONTACT if _parse(where, "in_contact", row["in_contact"], _boolean) else NO_CONTACT
        except UnicodeDecodeError as exc:
            raise DemonstrationError(f"{path}: not UTF-8 text ({exc})") from None
        except csv.Error as exc:
            raise DemonstrationError(f"{path}, line {reader.line_num}: not a readable CSV row ({exc})") from None
    return detections


def read_contact(path: str | os.PathLike, num_frames: int) -> np.ndarray:
    """Read a contact CSV: a header row with the column ``contact`` (0/1 or true/false) and
    optionally ``frame`` (then 0, 1, 2, ... in order), one row per video frame.

    Returns:
        (N,) bool.

    Raises:
        DemonstrationError: naming the file (and line), for a missing column, a value that
            is not 0/1, frames out of order, or a row count other than ``num_frames``.
        FileNotFoundError: ``path`` does not exist.
    """
    with open(path, newline="") as handle:
        reader = csv.DictReader(handle)
        columns = [name.strip() for name in reader.fieldnames or ()]
        if "contact" not in columns:
            raise DemonstrationError(f"{path}: no 'contact' column; expected a header row 'frame,contact' (or 'contact')")
        values = []
        for row in reader:
            row = {key.strip(): (value or "").strip() for key, value in row.items() if key is not None}
            where = f"{path}, line {reader.line_num}"
            if "frame" in columns and row.get("frame") != str(len(values)):
                raise DemonstrationError(f"{where}: frame {row.get('frame')!r}, expected {len(values)} (one row per frame, in order)")
            text = row.get("contact", "").lower()
            if text not in ("0", "1", "true", "false"):
                raise DemonstrationError(f"{where}: contact {row.get('contact')!r}: expected 0/1 or true/false")
            values.append(text in ("1", "true"))
    if len(values) != num_frames:
        raise DemonstrationError(f"{path}: {len(values)} contact rows, but the video has {num_frames} frames")
    return np.array(values, dtype=bool)


def _boolean(text: str) -> bool:
    """'1'/'0'/'true'/'false' (any case) -> bool."""
    value = text.strip().lower()
    if value in ("1", "true"):
        return True
    if value in ("0", "false"):
        return False
    raise ValueError(text)


def _parse(where: str, column: str, text: str | None, kind):
    """``kind(text)``, or a DemonstrationError naming ``where`` and ``column``."""
    try:
        return kind((text or "").strip())
    except ValueError:
        raise DemonstrationError(f"{where}: column {column}: cannot read {text!r} as {kind.__name__.lstrip('_')}") from None
