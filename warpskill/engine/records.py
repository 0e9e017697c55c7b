"""Typed records of the rollout: its inputs (:class:`SceneInputs`) and its output (:class:`Rollout`).

The same pair serves the Warp bridge (:func:`warpskill.engine.simulation.simulate`), the plain-Torch
references (:mod:`warpskill.engine.reference`), batching and the synthetic generator, so
that no argument order has to match by hand. :meth:`SceneInputs.check` is the one argument
check of every rollout.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import torch


class FieldSpec(NamedTuple):
    """Shape of an input with symbolic sizes ("B" scenes, "S" steps, "K" static cuboids), and
    its Warp value type: "vec3", "mat33" or "scalar"."""

    shape: tuple
    kind: str


def _spec(*shape, kind: str) -> dict:
    """Field metadata of an input: its :class:`FieldSpec`."""
    return {"spec": FieldSpec(tuple(shape), kind)}


@dataclass(frozen=True)
class SceneInputs:
    """The inputs of a rollout of B scenes of hand, manipulated cuboid and K static cuboids.

    All tensors share one dtype (float32 or float64) and one device; gradients reach every one.

    Attributes:
        hand_pos0: (B, 3) initial hand tip position [m].
        hand_rot0: (B, 3, 3) initial hand rotation (hand frame to world).
        grasp0: (B,) initial grasp signal g [m].
        hand_vel: (B, S, 7) per-step hand velocities: linear [m/s] (3), angular [rad/s] (3),
            grasp rate [m/s] (1); S = (N - 1) * steps_per_frame for N >= 2 frames.
        object_pos0: (B, 3) initial object centre [m]; the object starts at rest.
        object_rot0: (B, 3, 3) initial object rotation (object frame to world).
        object_size: (B, 3) full edge lengths of the object [m], positive.
        static_pos: (B, K, 3) static cuboid centres [m]; K may be 0.
        static_rot: (B, K, 3, 3) static cuboid rotations.
        static_size: (B, K, 3) static cuboid edge lengths [m], positive.
    """

    hand_pos0: torch.Tensor = field(metadata=_spec("B", 3, kind="vec3"))
    hand_rot0: torch.Tensor = field(metadata=_spec("B", 3, 3, kind="mat33"))
    grasp0: torch.Tensor = field(metadata=_spec("B", kind="scalar"))
    hand_vel: torch.Tensor = field(metadata=_spec("B", "S", 7, kind="scalar"))
    object_pos0: torch.Tensor = field(metadata=_spec("B", 3, kind="vec3"))
    object_rot0: torch.Tensor = field(metadata=_spec("B", 3, 3, kind="mat33"))
    object_size: torch.Tensor = field(metadata=_spec("B", 3, kind="vec3"))
    static_pos: torch.Tensor = field(metadata=_spec("B", "K", 3, kind="vec3"))
    static_rot: torch.Tensor = field(metadata=_spec("B", "K", 3, 3, kind="mat33"))
    static_size: torch.Tensor = field(metadata=_spec("B", "K", 3, kind="vec3"))

    @classmethod
    def specs(cls) -> dict[str, FieldSpec]:
        """Field name -> :class:`FieldSpec`, in field order."""
        return {f.name: f.metadata["spec"] for f in dataclasses.fields(cls)}

    def items(self) -> list[tuple[str, torch.Tensor]]:
        """(name, tensor) pairs in field order (the tensors themselves, not copies)."""
        return [(f.name, getattr(self, f.name)) for f in dataclasses.fields(self)]

    def tensors(self) -> tuple[torch.Tensor, ...]:
        """The tensors in field order (the Warp launch's and autograd's argument list)."""
        return tuple(tensor for _, tensor in self.items())

    def map(self, fn: Callable[[torch.Tensor], torch.Tensor]) -> SceneInputs:
        """A record of ``fn`` applied to every tensor."""
        return SceneInputs(*(fn(tensor) for tensor in self.tensors()))

    def to(self, *args, **kwargs) -> SceneInputs:
        """Every tensor through ``torch.Tensor.to(*args, **kwargs)`` (dtype and/or device)."""
        return self.map(lambda tensor: tensor.to(*args, **kwargs))

    @classmethod
    def cat(cls, scenes: Sequence[SceneInputs]) -> SceneInputs:
        """One batch of ``scenes`` (same K, dtype and device) along B, in order; shorter
        ``hand_vel`` are zero-padded at the end to the longest S (the hand holds still there)."""
        longest = max(scene.hand_vel.shape[1] for scene in scenes)
        pad = lambda v: torch.nn.functional.pad(v, (0, 0, 0, longest - v.shape[1]))
        return cls(**{
            name: torch.cat([pad(getattr(s, name)) if name == "hand_vel" else getattr(s, name) for s in scenes])
            for name in cls.specs()
        })

    def check(self, *, steps_per_frame: int | None = None, fps: float | None = None) -> dict[str, int]:
        """The argument check of every rollout: tensor types, float32/float64, one dtype and
        device, shapes, finiteness and positive sizes; with ``steps_per_frame`` (>= 1) that S is
        (N - 1) * steps_per_frame with N >= 2; with ``fps`` that it is positive.

        Returns:
            The symbolic sizes {"B", "S", "K"}.

        Raises:
            TypeError: ``self`` is not a :class:`SceneInputs` (the engine calls
                ``SceneInputs.check(inputs)``, so a plain dict is named here).
            ValueError: naming the offending field.
        """
        if not isinstance(self, SceneInputs):
            raise TypeError(f"rollout inputs must be a SceneInputs, got {type(self).__name__}")
        sizes: dict[str, int] = {}
        first = self.hand_pos0
        for name, tensor in self.items():
            if not isinstance(tensor, torch.Tensor):
                raise ValueError(f"{name} must be a torch.Tensor, got {type(tensor).__name__}")
            if tensor.dtype not in (torch.float32, torch.float64):
                raise ValueError(f"{name} must be float32 or float64, got {tensor.dtype}")
            if tensor.dtype != first.dtype:
                raise ValueError(f"{name} has dtype {tensor.dtype}, but hand_pos0 has {first.dtype}")
            if tensor.device != first.device:
                raise ValueError(f"{name} is on {tensor.device}, but hand_pos0 is on {first.device}")
            shape = self.specs()[name].shape
            expected = tuple(sizes.get(dim, "?") if isinstance(dim, str) else dim for dim in shape)
            if tensor.ndim != len(shape):
                raise ValueError(f"{name} must have shape {shape}, got {tuple(tensor.shape)}")
            for dim, size in zip(shape, tensor.shape):
                if isinstance(dim, str):
                    dim = sizes.setdefault(dim, size)
                if dim != size:
                    raise ValueError(f"{name} must have shape {expected}, got {tuple(tensor.shape)}")
        if not torch.isfinite(torch.cat([tensor.reshape(-1) for tensor in self.tensors()])).all():
            name = next(name for name, tensor in self.items() if not torch.isfinite(tensor).all())
            raise ValueError(f"{name} contains NaN or infinite values")
        if not (self.object_size > 0).all():
            raise ValueError("object_size must be positive")
        if not (self.static_size > 0).all():
            raise ValueError("static_size must be positive")
        if steps_per_frame is not None and steps_per_frame < 1:
            raise ValueError(f"steps_per_frame must be >= 1, got {steps_per_frame}")
        if fps is not None and not fps > 0:
            raise ValueError(f"fps must be positive, got {fps}")
        if steps_per_frame is not None and (sizes["S"] < steps_per_frame or sizes["S"] % steps_per_frame):
            raise ValueError(
                f"hand_vel must have (N - 1) * steps_per_frame steps with N >= 2, got {sizes['S']} steps "
                f"for steps_per_frame={steps_per_frame}"
            )
        return sizes


@dataclass
class Rollout:
    """Per-frame states of B scenes over N frames (Torch tensors, differentiable).

    Attributes:
        hand_pos: (B, N, 3) hand tip position [m].
        hand_rot: (B, N, 3, 3) hand rotation (hand frame to world).
        grasp: (B, N) grasp signal g [m].
        grasped: (B, N) grasp switch s in [0, 1] (1 = held).
        tip_distance: (B, N) signed distance of the hand tip to the object [m].
        object_pos: (B, N, 3) object centre [m].
        object_rot: (B, N, 3, 3) object rotation (object frame to world).
        object_vel: (B, N, 3) total linear velocity of the object [m/s].
        object_ang_vel: (B, N, 3) total angular velocity of the object [rad/s].
    """

    hand_pos: torch.Tensor
    hand_rot: torch.Tensor
    grasp: torch.Tensor
    grasped: torch.Tensor
    tip_distance: torch.Tensor
    object_pos: torch.Tensor
    object_rot: torch.Tensor
    object_vel: torch.Tensor
    object_ang_vel: torch.Tensor

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The field names in order."""
        return tuple(f.name for f in dataclasses.fields(cls))

    def map(self, fn: Callable[[torch.Tensor], torch.Tensor]) -> Rollout:
        """A rollout of ``fn`` applied to every tensor (e.g. ``lambda v: v[b : b + 1, :n]``)."""
        return Rollout(**{name: fn(getattr(self, name)) for name in self.names()})
