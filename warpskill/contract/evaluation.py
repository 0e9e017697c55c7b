"""The paper's success criteria for a reconstructed manipulation, as its released code computes them.

Each action has a few named checks on the reconstructed trajectories (world frame, z up,
x to the image's right, y away from the camera); a reconstruction succeeds when all
checks of its action pass. ``mode="original"`` reproduces two quirks of the released
code; the default ``"strict"`` fixes them:

- the hand-azimuth check of ``pull_right_to_left`` and ``push_left_to_right`` is skipped
  (a copy-paste bug in the released code made it unreachable);
- ``put_onto`` accepts an object centre within the static box's full size of its centre,
  instead of within half of it (the footprint).

Every check also has a **margin** [m]: how far its measured quantity is from flipping it,
positive when it passed with that much room, negative when it failed by that much (0: on its
limit). Checks of a distance against a limit measure that distance; the checks of a region
(behind, in front of, next to, over the static box) measure the final object centre's
distance to the region's nearest edge (when outside, the edge it misses by the most); the
checks of a share of frames measure the frame that decides the share (:func:`evaluate`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Literal

import numpy as np

from warpskill.contract.actions import ACTIONS, check_action, has_static_object
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.vocabulary import MODEL_HAND_LENGTH

Mode = Literal["strict", "original"]
MODES: tuple[str, ...] = ("strict", "original")

BELOW_GROUND_Z = -0.02  # [m] a corner lower than this is under the ground
MAX_FRACTION_BELOW_GROUND = 0.25
MIN_LATERAL_MOTION = 0.05  # [m] pull and push
MIN_AZIMUTH_FRACTION = 0.75  # of frames with the hand on the correct side
MIN_LIFT = 0.01  # [m] pick_up
START_ON_GROUND_Z = 0.01  # [m] pick_up: lowest corner at frame 0
PLACEMENT_ANGLE = 60.0  # [deg] "dang" of put_next_to / in_front_of / behind
ONTO_TOLERANCE = 0.03  # [m] lowest object corner to the static top, put_onto


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """The outcome of :func:`evaluate`.

    Attributes:
        success: whether every check passed.
        checks: check name -> passed, in evaluation order (see :func:`evaluate`).
        action: the action evaluated.
        margins: check name -> its signed margin [m] (see :func:`evaluate`; a check added by a
            caller may have none).
    """

    success: bool
    checks: dict[str, bool]
    action: str
    margins: dict[str, float] = dataclasses.field(default_factory=dict)

    def closest_call(self) -> tuple[str, float] | None:
        """The check nearest to flipping and its margin [m] (the smallest margin: negative when the
        evaluation failed); None without margins."""
        return closest_call(self.margins)


def evaluate(recon: Reconstruction, action: str | None = None, *, mode: Mode = "strict") -> Evaluation:
    """Apply the paper's success criteria for ``action`` to a reconstruction.

    Checks, by action (N frames; the object's 8 corners in every frame):

    - every action: ``above_ground``: in at most 25% of frames is the lowest corner below
      z = -0.02 m.
    - pull/push: ``moved_right`` (left_to_right; final centre x > first x + 0.05 m) or
      ``moved_left`` (right_to_left; final x < first x - 0.05 m); ``stayed_on_ground``: the
      centre's z range < the object's largest vertical extent over the video;
      ``hand_from_right`` (pull_left_to_right, push_right_to_left) or ``hand_from_left``
      (pull_right_to_left, push_left_to_right; skipped in ``"original"`` mode): the hand
      axis' azimuth atan2(y, x) has |az| < 90 deg (from the right) or > 90 deg (from the
      left) in more than 75% of frames.
    - pick_up: ``lifted``: final centre z > first z + 0.01 m; ``started_on_ground``: the
      lowest corner at frame 0 is below z = 0.01 m.
    - put_next_to / put_in_front_of / put_behind: ``next_to_static`` /
      ``in_front_of_static`` / ``behind_static`` from the angles of the final object centre
      seen from the corners of the static box's xy bounds; ``below_static_top``: the final
      lowest object corner is below the static box's top.
    - put_onto: ``over_static``: the final centre, in the static box's frame, lies within
      its footprint (``"original"``: within twice the footprint); ``on_static_top``: the
      final lowest object corner is within 3 cm of the static box's top.

    The static box is the reconstruction's first static object.

    Margins [m], by check (positive: passed with that much room; negative: failed by that much):

    - ``above_ground``: the height above z = -0.02 m of the lowest corner in the frame that
      decides the 25% (the lowest frame but a quarter of them).
    - ``moved_*``: the lateral motion beyond 0.05 m; ``stayed_on_ground``: the largest
      vertical extent less the centre's z range; ``lifted``: the rise beyond 0.01 m;
      ``started_on_ground``: the first frame's lowest corner below 0.01 m.
    - ``hand_from_*``: how far the hand axis' far end (0.4 m from the tip) lies on the correct
      side of the tip in x, in the frame that decides the 75%.
    - ``next_to_static`` / ``in_front_of_static`` / ``behind_static``: the final object
      centre's distance to the nearest limit line of its region (the lines of the angles from
      the static box's corners); outside, minus its distance to the line it is farthest beyond.
    - ``below_static_top``: the final lowest corner's depth below the static top.
    - ``over_static``: the final centre's distance inside the footprint's nearer edge (in the
      static box's frame; outside, minus its distance beyond the farther-off one);
      ``on_static_top``: 0.03 m less the final lowest corner's distance to the static top.

    Args:
        recon: the reconstruction.
        action: the action to evaluate; None for ``recon.action``.
        mode: ``"strict"`` (default) or ``"original"`` (the released code's quirks).

    Raises:
        ValueError: an unknown action or mode (also when ``action`` is None and the
            reconstruction's action is unknown), or a ``put_*`` action without a static
            object.
    """
    action = check_action(str(recon.action) if action is None else action)
    if mode not in MODES:
        raise ValueError(f"unknown mode {mode!r}; valid modes: {', '.join(MODES)}")
    if has_static_object(action) and recon.num_static == 0:
        raise ValueError(f"action {action} needs a static object, but the reconstruction has none")
    corners = recon.object_corners()
    judged = {"above_ground": _mostly_above_ground(corners)}
    if action == "pick_up":
        judged |= _pick_up_checks(recon, corners)
    elif action == "put_onto":
        judged |= _put_onto_checks(recon, corners, mode)
    elif has_static_object(action):
        judged |= _placement_checks(recon, corners, action)
    else:
        judged |= _lateral_checks(recon, corners, action, mode)
    checks = {name: passed for name, (passed, _) in judged.items()}
    return Evaluation(success=all(checks.values()), checks=checks, action=action,
                      margins={name: margin for name, (_, margin) in judged.items()})


def closest_call(margins: dict[str, float]) -> tuple[str, float] | None:
    """The check with the smallest margin and its margin [m]; None for no margins."""
    return min(margins.items(), key=lambda item: item[1]) if margins else None


def success_table(rows: dict[str, list[tuple[str, bool]]]) -> str:
    """The paper's success table as Markdown: one row per method, k/n per action.

    Args:
        rows: method name (e.g. "initialisation only", "full method") -> its results as
            (action, success) pairs, one per demonstration.

    Returns:
        A Markdown table with columns method, the 9 actions (k/n succeeded, "-" when
        none was run), total k/n and % succeeded (one decimal).

    Raises:
        ValueError: an unknown action name.
    """
    header = ["method", *ACTIONS, "total", "%"]
    body = []
    for method, results in rows.items():
        tally = {action: [0, 0] for action in ACTIONS}
        for action, success in results:
            tally[check_action(action)][0] += bool(success)
            tally[action][1] += 1
        done, runs = sum(k for k, _ in tally.values()), len(results)
        cells = [f"{k}/{n}" if n else "-" for k, n in tally.values()]
        percent = f"{100.0 * done / runs:.1f}" if runs else "-"
        body.append([method, *cells, f"{done}/{runs}", percent])
    widths = [max(len(row[i]) for row in [header, *body]) for i in range(len(header))]

    def line(cells: list[str]) -> str:
        return "| " + " | ".join(cell.ljust(width) for cell, width in zip(cells, widths)) + " |"

    return "\n".join([line(header), line(["-" * width for width in widths]), *map(line, body)])


Judged = tuple[bool, float]
"""A check's verdict and its margin [m]."""


def _beyond(value: float, limit: float) -> Judged:
    """``value > limit``, and by how much (``value - limit``, of the same sign)."""
    return bool(value > limit), float(value - limit)


def _mostly_above_ground(corners: np.ndarray) -> Judged:
    """At most 25% of frames have their lowest corner below -2 cm; ``corners`` (N, 8, 3).

    Margin: the lowest corner above -2 cm in the frame ranked just past the 25% allowed below."""
    lowest = corners[:, :, 2].min(axis=1)
    below = lowest < BELOW_GROUND_Z
    deciding = np.sort(lowest)[math.floor(MAX_FRACTION_BELOW_GROUND * len(lowest))]
    return bool(below.mean() <= MAX_FRACTION_BELOW_GROUND), float(deciding - BELOW_GROUND_Z)


def _lateral_checks(recon: Reconstruction, corners: np.ndarray, action: str, mode: Mode) -> dict[str, Judged]:
    """Checks of pull/push: the object slides sideways, the hand pushes or pulls from the correct side."""
    direction = 1.0 if action.endswith("left_to_right") else -1.0
    hand_side = direction if action.startswith("pull") else -direction  # +1: the arm is on the right
    x = recon.object_pos[:, 0]
    extents = corners[:, :, 2].max(axis=1) - corners[:, :, 2].min(axis=1)
    z = recon.object_pos[:, 2]
    checks = {
        "moved_right" if direction > 0 else "moved_left": _beyond(direction * (x[-1] - x[0]), MIN_LATERAL_MOTION),
        "stayed_on_ground": _beyond(extents.max(), z.max() - z.min()),
    }
    if hand_side > 0:
        checks["hand_from_right"] = _hand_from_side(recon, +1.0)
    elif mode == "strict":
        checks["hand_from_left"] = _hand_from_side(recon, -1.0)
    return checks


def _pick_up_checks(recon: Reconstruction, corners: np.ndarray) -> dict[str, Judged]:
    """Checks of pick_up: the object rises and starts on the ground."""
    z = recon.object_pos[:, 2]
    return {
        "lifted": _beyond(z[-1], z[0] + MIN_LIFT),
        "started_on_ground": _beyond(START_ON_GROUND_Z, corners[0, :, 2].min()),
    }


def _placement_checks(recon: Reconstruction, corners: np.ndarray, action: str) -> dict[str, Judged]:
    """Checks of put_next_to / put_in_front_of / put_behind: where the final object centre lies.

    Angles are seen from the corners of the static box's xy bounds; "bottom" is min y (the
    side nearer the camera), "left" min x. Each angle's range is a wedge of 150 deg at its
    corner, the meet of two half-planes; the margin is the least signed distance to their
    limit lines (:func:`_wedge_margin`), the better side's for next to.
    """
    static = recon.static_corners()[0]
    min_x, min_y = static[:, :2].min(axis=0)
    max_x, max_y = static[:, :2].max(axis=0)
    o_x, o_y = recon.object_pos[-1, :2]
    bl = math.degrees(math.atan2(o_y - min_y, o_x - min_x))
    br = math.degrees(math.atan2(o_y - min_y, o_x - max_x))
    tl = math.degrees(math.atan2(o_y - max_y, o_x - min_x))
    tr = math.degrees(math.atan2(o_y - max_y, o_x - max_x))
    dang = PLACEMENT_ANGLE
    centre, (b_l, b_r, t_l, t_r) = (o_x, o_y), ((min_x, min_y), (max_x, min_y), (min_x, max_y), (max_x, max_y))
    if action == "put_next_to":
        on_left = (bl < -180 + dang or bl > 90) and (tl > 180 - dang or tl < -90)
        on_right = (-dang < br < 90) and (-90 < tr < dang)
        left = min(_wedge_margin(centre, b_l, 90, 180 + dang), _wedge_margin(centre, t_l, 180 - dang, 270))
        right = min(_wedge_margin(centre, b_r, -dang, 90), _wedge_margin(centre, t_r, -90, dang))
        name, placed, margin = "next_to_static", on_left or on_right, max(left, right)
    elif action == "put_in_front_of":
        name, placed = "in_front_of_static", (-90 - dang < bl < 0) and (-180 < br < -90 + dang)
        margin = min(_wedge_margin(centre, b_l, -90 - dang, 0), _wedge_margin(centre, b_r, -180, -90 + dang))
    else:
        name, placed = "behind_static", (0 < tl < 90 + dang) and (90 - dang < br < 180)
        margin = min(_wedge_margin(centre, t_l, 0, 90 + dang), _wedge_margin(centre, b_r, 90 - dang, 180))
    return {name: (placed, margin), "below_static_top": _beyond(static[:, 2].max(), corners[-1, :, 2].min())}


def _wedge_margin(point: tuple[float, float], apex: tuple[float, float], low: float, high: float) -> float:
    """Signed distance [m] of ``point`` into the wedge at ``apex`` between the directions ``low``
    and ``high`` [deg, counter-clockwise, less than 180 apart]: the least of its distances to the
    two limit lines, positive inside both half-planes."""
    dx, dy = point[0] - apex[0], point[1] - apex[1]
    low, high = math.radians(low), math.radians(high)
    past_low = math.cos(low) * dy - math.sin(low) * dx  # > 0: counter-clockwise of the low direction
    before_high = math.sin(high) * dx - math.cos(high) * dy  # > 0: clockwise of the high direction
    return float(min(past_low, before_high))


def _put_onto_checks(recon: Reconstruction, corners: np.ndarray, mode: Mode) -> dict[str, Judged]:
    """Checks of put_onto: the final object centre is over the static box and rests on its top."""
    static_top = recon.static_corners()[0, :, 2].max()
    centre_in_static = recon.static_rot[0].T @ (recon.object_pos[-1] - recon.static_pos[0])
    limit = recon.static_size[0, :2] / (1.0 if mode == "original" else 2.0)
    return {
        "over_static": _beyond(np.min(limit - np.abs(centre_in_static[:2])), 0.0),
        "on_static_top": _beyond(ONTO_TOLERANCE, abs(corners[-1, :, 2].min() - static_top)),
    }


def _hand_from_side(recon: Reconstruction, side: float) -> Judged:
    """The hand axis points to ``side`` (+1: the right, |azimuth| < 90 deg; -1: the left) in more
    than 75% of frames. Margin: the far end's x beyond the tip's (``side`` x 0.4 m x the axis' x)
    in the frame ranked at the 75%-and-one."""
    azimuth = np.abs(_hand_azimuth_deg(recon))
    passed = _mostly(azimuth < 90.0 if side > 0 else azimuth > 90.0)
    reach = np.sort(side * MODEL_HAND_LENGTH * recon.hand_rot[:, 0, 2])[::-1]
    return passed, float(reach[math.floor(MIN_AZIMUTH_FRACTION * len(reach))])


def _hand_azimuth_deg(recon: Reconstruction) -> np.ndarray:
    """(N,) azimuth [deg] of the hand axis (local +z, from the tip towards the arm) in the world."""
    axis = recon.hand_rot[:, :, 2]
    return np.degrees(np.arctan2(axis[:, 1], axis[:, 0]))


def _mostly(flags: np.ndarray) -> bool:
    """True in more than 75% of frames."""
    return bool(flags.sum() > MIN_AZIMUTH_FRACTION * flags.shape[0])
