"""The differentiable engine: Torch autograd bridges over the Warp kernels, and their references.

Owns the rollout (:func:`simulate`, :mod:`.simulation`, over the records :class:`SceneInputs`
and :class:`Rollout` of :mod:`.records`), the soft silhouettes
(:func:`render_silhouettes`, and :func:`silhouette_profiles`, what the mask losses read of
them, :mod:`.rendering`), the scene primitives, the camera's
projection, the exact NumPy ray cast, small differentiable geometry and rotation helpers,
and :mod:`.reference` (the plain-Torch oracle and the paper's dopri5 integrator). May
import :mod:`warpskill.kernels`, :mod:`warpskill.contract`, torch and Warp; never the
optimiser, data, robot or tools.
"""

from warpskill.engine.device import resolve_device
from warpskill.engine.raycast import raycast_masks
from warpskill.engine.records import Rollout, SceneInputs
from warpskill.engine.rendering import render_silhouettes, silhouette_profiles
from warpskill.engine.simulation import PhysicsConfig, simulate, substeps_per_frame

__all__ = [
    "PhysicsConfig",
    "Rollout",
    "SceneInputs",
    "raycast_masks",
    "render_silhouettes",
    "resolve_device",
    "silhouette_profiles",
    "simulate",
    "substeps_per_frame",
]
