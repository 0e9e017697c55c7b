"""The two-stage optimisation of the paper: a demonstration in, a reconstruction out.

Owns the pipeline (:func:`optimize`, :func:`optimize_many`; :mod:`.pipeline`), the
hypotheses it tries and chooses between (:mod:`.hypotheses`), its settings
(:class:`OptimizeOptions`, :class:`OptimizeConfig`, :class:`LossWeights`), the working
inputs (:mod:`.inputs`), the masks' measurements (:mod:`.measurements`) and the first guess
read off them (:mod:`.guess`), the scene both stages share (:mod:`.scene`), stage (a)
(:mod:`.stage_a`: a physics-free fit of per-frame poses) and stage (b) (:mod:`.stage_b`: the
physics scene and its objective), the Adam loop (:mod:`.loop`) and its checkpoints,
batching of many scenes per engine call, and the mask losses. May import
:mod:`warpskill.engine` and :mod:`warpskill.contract`; never data, robot, bench or visual.
"""

from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.known import KNOWN_LENGTHS, parse_known
from warpskill.optimizer.options import OptimizeOptions
from warpskill.optimizer.pipeline import optimize, optimize_many
from warpskill.optimizer.weights import LossWeights

__all__ = ["KNOWN_LENGTHS", "LossWeights", "OptimizeConfig", "OptimizeOptions", "optimize", "optimize_many", "parse_known"]
