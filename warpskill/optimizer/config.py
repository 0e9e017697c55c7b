"""Settings of :func:`warpskill.optimize`: iterations, learning rates, resolution, schedule, weights, physics."""

from __future__ import annotations

from dataclasses import dataclass, field

from warpskill.engine.simulation import PhysicsConfig
from warpskill.optimizer.weights import LossWeights


@dataclass(frozen=True)
class OptimizeConfig:
    """Settings of :func:`optimize`. The defaults are the ones the benchmarks report."""

    iterations: int = 250  #: physics-stage iterations (upper bound; stops early once the lr has decayed)
    init_iterations: int = 150  #: stage (a) iterations
    #: stage (a)'s successive halving of the object-depth hypotheses: after each (iteration,
    #: margin), a hypothesis whose loss is more than the margin (relative) above the best stops
    rival_rungs: tuple[tuple[int, float], ...] = ((25, 0.5), (50, 0.2), (75, 0.1), (100, 0.05))
    learning_rate: float = 5e-3  #: physics stage (the paper's)
    init_learning_rate: float = 1e-2  #: stage (a)
    image_scale: float = 0.25  #: working resolution relative to the masks
    #: stage (a)'s first iterations run at ``coarse_scale`` of the working resolution (coarse to fine)
    coarse_iterations: int = 50
    coarse_scale: float = 0.5
    sigma: float = 0.35  #: soft edge width [px at the working resolution]: about the edge of area-averaged masks
    knots_per_second: float = 3.0  #: density of the hand's velocity spline
    pre_roll: float = 0.5  #: still time simulated before the video [s]
    post_roll: float = 1.0  #: still time simulated after the video [s]
    plateau_patience: int = 10  #: iterations without improvement before the lr is halved
    plateau_factor: float = 0.5
    min_lr_ratio: float = 0.1  #: stop once the lr falls below this fraction of its start
    #: stop a module once its best loss has fallen by less than ``converge_tolerance`` (relative)
    #: over the last ``converge_window`` iterations (0: never; the lr floor above still stops it)
    converge_window: int = 30
    converge_tolerance: float = 1e-3
    warmup_iterations: int = 10  #: the learning rate ramps up linearly over these iterations
    #: try the object on the ground behind the static box (ObjectDepth.BEHIND) for every action, not only put behind
    behind_placement: bool = False
    checkpoint_every: int = 25  #: iterations between checkpoint writes
    weights: LossWeights = field(default_factory=LossWeights)
    physics: PhysicsConfig = field(default_factory=PhysicsConfig)
