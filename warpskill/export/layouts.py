"""Random layouts of a skill over the Panda's reachable table: a documented, seeded distribution.

:class:`ReachableTable` is the part of the table the robot reaches comfortably, an annular
sector in front of its base: distances :data:`INNER` .. :data:`OUTER` from the base's
vertical axis, bearings within :data:`HALF_ANGLE` of its forward axis. The base is where the
robot stands for the demonstrated layout (:func:`~warpskill.robot.model.make_scene`'s
default placement: the scene centre 0.5 m ahead, the robot facing world +y).

:func:`layouts` draws, independently per layout:

- the object's start: uniform over the sector's area, yaw uniform in [-pi, pi);
- each static box: uniform over the sector's area, yaw uniform in [-pi, pi);

and keeps a draw only where the action still makes sense, decided from the geometry before
any planning (a refused draw is drawn again, and counted by its reason: :func:`layouts`'s
``redrawn``): the boxes' start footprints do not
touch (:func:`~warpskill.robot.skill_layout.overlap_depth` 0) nor reach within
:data:`BASE_CLEARANCE` of the robot's base axis (nor does the object anywhere on its path),
:func:`~warpskill.robot.skill_layout.apply_skill` accepts it (no path through a static box, the
relation met where the skill releases the object: beside, behind, in front of or on the
static box as the action's checks judge it) and the object's whole held
path, the ``put_*`` release beside or on the box included, keeps
:data:`~warpskill.robot.placement.REACH_MARGIN` (5 cm) inside the Panda's reach from some base
placement that the retargeting searches (:func:`~warpskill.robot.placement.check_reach`, the
test the retargeting applies to a layout: every layout drawn is one it accepts). The path is
not held to the sector: the robot stands where the layout's scene needs it. The path moves no
faster than :data:`~warpskill.robot.skill_layout.SWING_SPEED` (a ``put_*`` path bent towards a
far box could), and an object held from the first frame starts resting on the table (within
:data:`START_HEIGHT`), not lifted over a box beside it.
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter
from collections.abc import Iterator

import numpy as np

from warpskill.contract.skill import Layout, LayoutError, Skill
from warpskill.geometry import is_held
from warpskill.robot.model import make_scene
from warpskill.robot.placement import check_reach
from warpskill.robot.skill_layout import SWING_SPEED, apply_skill, demonstrated_layout, overlap_depth

__all__ = ["BASE_CLEARANCE", "HALF_ANGLE", "INNER", "OUTER", "ReachableTable", "layouts", "sample_layouts"]

INNER = 0.35  # [m] nearest reach from the base's axis (closer, the arm folds onto itself)
OUTER = 0.70  # [m] farthest comfortable reach at table height (the Panda's limit is about 0.85 m)
HALF_ANGLE = math.radians(50.0)  # [rad] bearings either side of the robot's forward axis
MAX_DRAWS = 1000  # draws per layout before giving up
START_HEIGHT = 0.01  # [m] an object held from the first frame starts with its bottom at most this high
BASE_CLEARANCE = 0.15  # [m] nearest a box may start to the base's axis (its column is about 0.11 m in radius)


@dataclasses.dataclass(frozen=True)
class ReachableTable:
    """The annular sector of the table in front of a robot base (see the module doc).

    Attributes:
        base: (4, 4) pose of the robot base in the world.
        inner, outer: [m] radii of the sector.
        half_angle: [rad] half its opening.
    """

    base: np.ndarray
    inner: float = INNER
    outer: float = OUTER
    half_angle: float = HALF_ANGLE

    @classmethod
    def of(cls, skill: Skill) -> "ReachableTable":
        """The sector in front of the robot placed for the skill's demonstrated layout."""
        return cls(base=make_scene(apply_skill(skill, demonstrated_layout(skill))).base)

    def polar(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distances [m] and bearings [rad] of world points (..., 2) from the base."""
        local = (np.asarray(xy, float) - self.base[:2, 3]) @ self.base[:2, :2]
        return np.hypot(local[..., 0], local[..., 1]), np.arctan2(local[..., 1], local[..., 0])

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """Whether world points (..., 2) [m] lie on the sector."""
        radius, bearing = self.polar(xy)
        return (radius >= self.inner) & (radius <= self.outer) & (np.abs(bearing) <= self.half_angle)

    def clear_of_base(self, pos: np.ndarray, rot: np.ndarray, size: np.ndarray) -> bool:
        """Whether a box (centre (3,) [m], rotation (3, 3), edges (3,) [m]) keeps at least
        :data:`BASE_CLEARANCE` from the base's vertical axis: a long object centred on the
        sector can still reach into the robot."""
        axis_point = np.array([*self.base[:2, 3], pos[2]])  # the axis at the box centre's height
        local = np.abs(rot.T @ (axis_point - pos)) - 0.5 * np.asarray(size)
        return bool(np.linalg.norm(np.maximum(local, 0.0)) >= BASE_CLEARANCE)

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        """(2,) a world point uniform over the sector's area."""
        radius = math.sqrt(rng.uniform(self.inner**2, self.outer**2))
        bearing = rng.uniform(-self.half_angle, self.half_angle)
        local = radius * np.array([math.cos(bearing), math.sin(bearing)])
        return self.base[:2, :2] @ local + self.base[:2, 3]


def layouts(skill: Skill, *, seed: int = 0, table: ReachableTable | None = None,
            redrawn: Counter[str] | None = None) -> Iterator[Layout]:
    """Endless random layouts of ``skill`` (the module doc's distribution), reproducible by ``seed``.

    Args:
        redrawn: where to count each draw refused, and so drawn again, by its reason (a few words:
            ``"out of reach"``, ``"relation not met"``, ...), before any planning.

    Raises:
        LayoutError: :data:`MAX_DRAWS` draws in a row were all refused (a skill whose path
            does not fit on the sector); the message names the commonest reasons.
    """
    table = table or ReachableTable.of(skill)
    rng = np.random.default_rng(seed)
    while True:
        refusals: Counter[str] = Counter()
        for _ in range(MAX_DRAWS):
            layout = _draw(skill, table, rng)
            reason = _refusal(skill, layout, table)
            if not reason:
                yield layout
                break
            refusals[reason] += 1
            if redrawn is not None:
                redrawn[reason] += 1
        else:
            raise LayoutError(f"no layout of the {skill.action} skill fits the reachable table in {MAX_DRAWS} "
                              f"draws ({_commonest(refusals)})")


def _commonest(refusals: Counter[str], shown: int = 2) -> str:
    """The ``shown`` commonest refusal reasons with their counts, e.g. ``"out of reach: 870, ..."``."""
    return ", ".join(f"{reason}: {count}" for reason, count in refusals.most_common(shown))


def sample_layouts(skill: Skill, count: int, *, seed: int = 0, table: ReachableTable | None = None) -> list[Layout]:
    """The first ``count`` layouts of :func:`layouts`."""
    draws = layouts(skill, seed=seed, table=table)
    return [next(draws) for _ in range(count)]


def _draw(skill: Skill, table: ReachableTable, rng: np.random.Generator) -> Layout:
    def pose():
        return (*table.sample(rng), rng.uniform(-math.pi, math.pi))

    return Layout(object=pose(), statics=tuple(pose() for _ in range(skill.num_static)))


def _refusal(skill: Skill, layout: Layout, table: ReachableTable) -> str:
    """Why ``layout`` is refused (the module doc's conditions, in a few words), or "" if it is kept."""
    try:
        recon = apply_skill(skill, layout)
    except LayoutError as error:  # overlapping boxes, a path into a static box, the relation not met
        return error.reason
    boxes = [(recon.object_pos[0], recon.object_rot[0], recon.object_size),
             *zip(recon.static_pos, recon.static_rot, recon.static_size)]
    # Footprints: each pair compared at one height (an object held from the first frame may start
    # lifted over a box it stands on).
    level = lambda box, z: (np.array([*box[0][:2], z]), *box[1:])  # noqa: E731
    if not all(overlap_depth(*boxes[i], *level(boxes[j], boxes[i][0][2])) == 0.0
               for i in range(len(boxes)) for j in range(i + 1, len(boxes))):
        return "footprints overlap"
    path = zip(recon.object_pos, recon.object_rot)
    if not (all(table.clear_of_base(*box) for box in boxes)
            and all(table.clear_of_base(pos, rot, recon.object_size) for pos, rot in path)):
        return "too near the robot's base"
    if is_held(recon.grasped[0]) and recon.object_corners()[0, :, 2].min() > START_HEIGHT:
        return "carried-in object starts lifted"  # over a box beside its start
    if np.max(np.linalg.norm(np.diff(recon.object_pos, axis=0), axis=1)) * float(recon.fps) > SWING_SPEED:
        return "path swings too fast"  # the put's path bent so far towards the box
    try:
        check_reach(recon)
    except LayoutError as error:
        return error.reason
    return ""
