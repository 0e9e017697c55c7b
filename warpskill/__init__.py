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

__all__, __getattr__, __dir__ = lazy_exports(__name__, globals(), {
    "contract.actions": ("ACTIONS",),
    "contract.demonstration": ("Demonstration", "DemonstrationError"),
    "contract.reconstruction": ("Reconstruction", "ReconstructionError"),
    "optimizer.pipeline": ("optimize", "optimize_many"),
    "optimizer.config": ("OptimizeConfig",),
    "optimizer.options": ("OptimizeOptions",),
    "optimizer.weights": ("LossWeights",),
    "contract.evaluation": ("evaluate", "Evaluation"),
    "engine.simulation": ("simulate", "PhysicsConfig"),
    "engine.rendering": ("render_silhouettes",),
    "synthetic": ("make_demonstration",),
    "robot.retargeting": ("retarget",),
    "robot.replaying": ("replay",),
    "robot.plan": ("RobotPlan", "PlanError"),
    "contract.replay": ("Replay",),
    "contract.camera": ("Intrinsics",),
    "contract.skill": ("Skill", "Layout", "LayoutError"),
    "robot.skill_layout": ("skill_from",),
    "visual.pictures": ("save_pictures",),
    "visual.rerun_view": ("view",),
    None: ("contract", "data", "engine", "optimizer", "robot", "visual", "cluster", "bench"),
})
