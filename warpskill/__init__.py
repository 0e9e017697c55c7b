"""warpskill: learn a manipulation skill from one video via approximate differentiable physics.

The public API, loaded on first use (so the command line starts fast):

- data: :class:`Demonstration`, :class:`Reconstruction`, :data:`ACTIONS`
- reconstruction: :func:`optimize`, :func:`optimize_many`, :class:`OptimizeOptions`, :class:`OptimizeConfig`, :class:`LossWeights`
- metric: :func:`evaluate`
- skill: :func:`skill_from` -> :class:`Skill`, carried to a :class:`Layout` (:func:`warpskill.robot.skill_layout.apply_skill`)
- engine: :func:`simulate`, :class:`PhysicsConfig`, :func:`render_silhouettes`
- synthetic data: :func:`make_demonstration`
- robot (extra ``warpskill[robot]``): :func:`retarget`, :func:`replay`, :class:`RobotPlan`, :class:`Replay`
- the layers, as submodules: :mod:`contract`, :mod:`data` (readers of real recordings),
  :mod:`engine`, :mod:`optimizer`, :mod:`robot`, :mod:`visual`, :mod:`bench`
  (``docs/architecture.md`` draws them and their import rules)
"""

from __future__ import annotations

from warpskill.lazy import lazy_exports

__version__ = "0.1.0"

_EXPORTS = {
    "ACTIONS": "contract.actions",
    "Demonstration": "contract.demonstration",
    "DemonstrationError": "contract.demonstration",
    "Reconstruction": "contract.reconstruction",
    "ReconstructionError": "contract.reconstruction",
    "optimize": "optimizer.pipeline",
    "optimize_many": "optimizer.pipeline",
    "OptimizeConfig": "optimizer.config",
    "OptimizeOptions": "optimizer.options",
    "LossWeights": "optimizer.weights",
    "evaluate": "contract.evaluation",
    "Evaluation": "contract.evaluation",
    "simulate": "engine.simulation",
    "PhysicsConfig": "engine.simulation",
    "render_silhouettes": "engine.rendering",
    "make_demonstration": "synthetic",
    "retarget": "robot.retargeting",
    "replay": "robot.replaying",
    "RobotPlan": "robot.plan",
    "PlanError": "robot.plan",
    "Replay": "contract.replay",
    "Intrinsics": "contract.camera",
    "Skill": "contract.skill",
    "Layout": "contract.skill",
    "LayoutError": "contract.skill",
    "skill_from": "robot.skill_layout",
    "save_pictures": "visual.pictures",
    "view": "visual.rerun_view",
    **{layer: None for layer in ("contract", "data", "engine", "optimizer", "robot", "visual", "cluster", "bench")},
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
