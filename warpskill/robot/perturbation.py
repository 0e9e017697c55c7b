"""What a real robot meets and a plan must survive: another mass or friction, an object a little off.

A :class:`Perturbation` edits the built MuJoCo model of a replay in place (the
``edit_model`` hook of :func:`warpskill.robot.replay`): the object's mass (and inertia,
same density), the sliding friction of every geom (a contact takes the larger of its
two geoms', so every contact changes by the same factor) and the object's start pose
(shifted and turned about z from where the plan expects it). :data:`PERTURBATIONS` is the
set a plan is *robust* to when its replay succeeds under each.
"""

from __future__ import annotations

import dataclasses
import math

from warpskill.geometry import quat_multiply
from warpskill.robot.replay_mujoco import OBJECT_BODY, OBJECT_JOINT

__all__ = ["PERTURBATIONS", "Perturbation"]



@dataclasses.dataclass(frozen=True)
class Perturbation:
    """One change of the simulated world.

    Attributes:
        name: how tables name it.
        mass_scale: factor on the object's mass and inertia [-].
        friction_scale: factor on every geom's sliding friction [-].
        shift: (dx, dy) [m] of the object's start, world frame.
        turn: [rad] of the object's start about the world z axis (about its centre).
    """

    name: str
    mass_scale: float = 1.0
    friction_scale: float = 1.0
    shift: tuple[float, float] = (0.0, 0.0)
    turn: float = 0.0

    def __call__(self, model) -> None:
        """Change ``model`` (a ``mujoco.MjModel`` built by ``replay_mujoco.build_model``) in place."""
        body = model.body(OBJECT_BODY).id
        model.body_mass[body] *= self.mass_scale
        model.body_inertia[body] *= self.mass_scale
        model.geom_friction[:, 0] *= self.friction_scale
        start = model.jnt_qposadr[model.joint(OBJECT_JOINT).id]
        model.qpos0[start:start + 2] += self.shift
        half = 0.5 * self.turn  # a turn about world z, after the start's own rotation
        turn = (math.cos(half), 0.0, 0.0, math.sin(half))
        model.qpos0[start + 3:start + 7] = quat_multiply(turn, model.qpos0[start + 3:start + 7])


PERTURBATIONS: tuple[Perturbation, ...] = (
    Perturbation("mass x0.5", mass_scale=0.5),
    Perturbation("mass x2", mass_scale=2.0),
    Perturbation("friction -30%", friction_scale=0.7),
    Perturbation("friction +30%", friction_scale=1.3),
    Perturbation("off 1 cm, 5 deg", shift=(0.01 / math.sqrt(2), 0.01 / math.sqrt(2)), turn=math.radians(5.0)),
)
"""The perturbations of the robust column: mass x0.5 and x2, friction -30 % and +30 %, and
the object 1 cm off (diagonally in x and y) and turned 5 deg from where it was expected."""
