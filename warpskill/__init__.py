"""warpskill: learn a manipulation skill from one video via approximate differentiable physics.

The public API, loaded on first use (so the command line starts fast):

- data: :class:`Demonstration`, :class:`Reconstruction`, :data:`ACTIONS`
- reconstruction: :func:`optimize`, :func:`optimize_many`, :class:`OptimizeConfig`, :class:`LossWeights`
- metric: :func:`evaluate`
- engine: :func:`simulate`, :class:`PhysicsConfig`, :func:`render_silhouettes`
- synthetic data: :func:`make_demonstration`
- robot (extra ``warpskill[robot]``): :func:`retarget`, :func:`replay`, :class:`RobotPlan`
"""

from __future__ import annotations

from ._lazy import lazy_exports

__version__ = "0.1.0"

_EXPORTS = {
    "ACTIONS": "actions",
    "Demonstration": "demonstration",
    "DemonstrationError": "demonstration",
    "Reconstruction": "reconstruction",
    "ReconstructionError": "reconstruction",
    "optimize": "optimization",
    "optimize_many": "optimization",
    "OptimizeConfig": "optimization",
    "LossWeights": "weights",
    "evaluate": "evaluation",
    "Evaluation": "evaluation",
    "simulate": "physics",
    "PhysicsConfig": "physics",
    "render_silhouettes": "render",
    "make_demonstration": "synthetic",
    "retarget": "robot.retargeting",
    "replay": "robot.replaying",
    "RobotPlan": "robot.plan",
    "PlanError": "robot.plan",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
