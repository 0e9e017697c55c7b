"""Differentiable rollout of hand and manipulated cuboid: Torch autograd over Warp kernels.

``simulate`` integrates B scenes (a :class:`~warpskill.engine.records.SceneInputs`) with the
semi-implicit scheme of ``kernels/integrator.py`` (see docs/architecture.md, "Physics") and
returns per-frame states as a :class:`~warpskill.engine.records.Rollout` of Torch tensors. The
forward pass records the Warp launches on a ``wp.Tape``; the backward pass replays it.
Float32 tensors run the float32 kernels, float64 tensors the float64 ones.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass

import torch
import warp as wp

from warpskill.engine.records import Rollout, SceneInputs
from warpskill.engine.warp_bridge import WorkspacePool, as_warp, copy_into, make_struct, warp_scope
from warpskill.kernels.integrator import gather_frames, rollout, scratch, trajectory
from warpskill.kernels.records import records

__all__ = ["PhysicsConfig", "Rollout", "SceneInputs", "simulate", "substeps_per_frame"]


@dataclass(frozen=True)
class PhysicsConfig:
    """Constants of the approximate physics (defaults: the paper's released code).

    Attributes:
        kp: contact stiffness [1/s^2].
        kv: contact damping [1/s].
        mu: tangential velocity damping standing in for friction [1/s].
        gravity: gravitational acceleration [m/s^2], acting along -z.
        free_damping: linear and angular damping c of the free object [1/s].
        grasp_decay: decay k_g of the object's own velocity while grasped [1/s].
        grasp_tau: width tau of the grasp switch's sigmoids [m].
        max_dt: largest stable integration step [s].
    """

    kp: float = 500.0
    kv: float = 5.0
    mu: float = 10.0
    gravity: float = 9.81
    free_damping: float = 0.5
    grasp_decay: float = 100.0
    grasp_tau: float = 0.001
    max_dt: float = 1.0 / 240.0


def substeps_per_frame(fps: float, config: PhysicsConfig = PhysicsConfig()) -> int:
    """Integration steps per frame, ceil(1 / (fps * max_dt)): 20 at 12 fps."""
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    return max(1, math.ceil(round(1.0 / (fps * config.max_dt), 9)))


class _Workspace:
    """The rollout's arrays for one shape, allocated once and reused, in the kernels' records
    (:mod:`warpskill.kernels.records`): the inputs ``inputs`` (a :class:`~warpskill.engine.records.SceneInputs`
    of Torch tensors, B scenes, S steps, K statics) under the record ``scene``, the per-step states ``steps``
    (B, S + 1), the per-frame ones ``frames`` (B, N) and the ``scratch``, with gradient buffers where
    ``requires_grad``: Torch views of the inputs' gradients ``input_grads``, of the frames' ``frame_grads``
    (:class:`Rollout` field order), and the Warp gradients of all the records' arrays, ``grads``. A call takes one from :data:`_POOL` and gives
    it back once its backward pass has run (at once without one), its gradients zeroed for the next."""

    def __init__(self, key: tuple):
        num_scenes, num_steps, num_frames, num_statics, scalar, device, requires_grad = self.key = key
        torch_device = wp.device_to_torch(device)
        sizes = {"B": num_scenes, "S": num_steps, "K": num_statics}
        value_types = {"vec3": wp.types.vector(3, scalar), "mat33": wp.types.matrix((3, 3), scalar), "scalar": scalar}
        dtype = torch.float64 if scalar == wp.float64 else torch.float32
        self.inputs = SceneInputs(**{
            name: torch.zeros([sizes.get(n, n) for n in spec.shape], dtype=dtype, device=torch_device)
            for name, spec in SceneInputs.specs().items()
        })
        self.scene = make_struct(records(scalar).Scene, **{
            name: as_warp(tensor, value_types[SceneInputs.specs()[name].kind], requires_grad)
            for name, tensor in self.inputs.items()})
        self.steps = trajectory(num_scenes, num_steps + 1, scalar, device, requires_grad)
        self.frames = trajectory(num_scenes, num_frames, scalar, device, requires_grad)
        self.scratch = scratch(num_scenes, num_steps, scalar, device, requires_grad)
        if requires_grad:
            kinds = records(scalar)
            self.grads = [getattr(record, name).grad for record, kind in
                          ((self.scene, kinds.Scene), (self.steps, kinds.Trajectory), (self.frames, kinds.Trajectory),
                           (self.scratch, kinds.Scratch)) for name in kind.vars]
            self.input_grads = _torch_grads(self.scene, SceneInputs.specs())
            self.frame_grads = _torch_grads(self.frames, Rollout.names())


def _torch_grads(record, names) -> list[torch.Tensor]:
    """Torch views of the gradients of the arrays ``names`` of the struct instance ``record``."""
    return [wp.to_torch(getattr(record, name).grad, requires_grad=False) for name in names]


_POOL = WorkspacePool(_Workspace)


def _launch(config: PhysicsConfig, steps_per_frame: int, dt: float, inputs: SceneInputs, requires_grad: bool):
    """Run the rollout of ``inputs`` (copied into a workspace from the pool); returns the tape and
    the :class:`_Workspace` (its ``frames`` the per-frame trajectory). Launches are recorded on the
    tape if ``requires_grad``."""
    wp.init()
    device = inputs.hand_pos0.device
    scalar = wp.float64 if inputs.hand_pos0.dtype == torch.float64 else wp.float32
    num_scenes, num_steps = inputs.hand_vel.shape[:2]
    key = (num_scenes, num_steps, num_steps // steps_per_frame + 1, inputs.static_pos.shape[1], scalar,
           str(wp.device_from_torch(device)), requires_grad)
    work = _POOL.take(key)
    copy_into(work.inputs.tensors(), inputs.tensors())
    physics = make_struct(records(scalar).Physics, dt=dt, **{
        name: getattr(config, name) for name in ("kp", "kv", "mu", "gravity", "free_damping", "grasp_decay",
                                                 "grasp_tau")})
    tape = wp.Tape()
    with warp_scope(device), tape if requires_grad else contextlib.nullcontext():
        work.scratch.impulse_v.zero_()
        work.scratch.impulse_w.zero_()
        rollout(physics, work.scene, work.steps, work.scratch)
        gather_frames(steps_per_frame, work.steps, work.frames)
    return tape, work


def _to_torch(frames) -> tuple[torch.Tensor, ...]:
    """Torch copies of the frames' arrays in :class:`Rollout` field order (the workspace is reused)."""
    return tuple(wp.to_torch(getattr(frames, name), requires_grad=False).clone() for name in Rollout.names())


class _Simulate(torch.autograd.Function):
    """Autograd bridge: forward records the Warp rollout on a tape, backward replays it.
    The tensors are those of a :class:`SceneInputs`, in field order."""

    @staticmethod
    def forward(ctx, config: PhysicsConfig, steps_per_frame: int, dt: float, *tensors: torch.Tensor):
        ctx.set_materialize_grads(False)  # unused outputs seed nothing
        ctx.device = tensors[0].device
        ctx.tape, ctx.work = _launch(config, steps_per_frame, dt, SceneInputs(*tensors), requires_grad=True)
        return _to_torch(ctx.work.frames)

    @staticmethod
    def backward(ctx, *grad_outputs: torch.Tensor):
        work = ctx.work
        seeded = [(seed, grad) for seed, grad in zip(work.frame_grads, grad_outputs) if grad is not None]
        if seeded:  # into the frames' own .grad buffers (zeroed after the last backward pass)
            copy_into(*zip(*seeded))
        with warp_scope(ctx.device):
            ctx.tape.backward()
            input_grads = [grad.clone() if needed else None
                           for grad, needed in zip(work.input_grads, ctx.needs_input_grad[3:])]
            for grad in work.grads:  # the tape's zero() leaves a struct's arrays' gradients
                grad.zero_()
        _POOL.give_back(work.key, work)
        return (None, None, None, *input_grads)


def simulate(
    inputs: SceneInputs,
    *,
    steps_per_frame: int,
    fps: float,
    config: PhysicsConfig = PhysicsConfig(),
) -> Rollout:
    """Roll out B scenes of hand, manipulated cuboid and K static cuboids.

    The step is dt = 1 / (fps * steps_per_frame) [s]; the object starts at rest. Gradients
    reach every input tensor.

    Args:
        inputs: the B scenes (see :class:`~warpskill.engine.records.SceneInputs`: one dtype,
            float32 or float64, and one device); ``hand_vel`` has S = (N - 1) * steps_per_frame
            steps for N >= 2 frames.
        steps_per_frame: integration steps per frame (see :func:`substeps_per_frame`).
        fps: frame rate [1/s].
        config: physics constants.

    Returns:
        The :class:`~warpskill.engine.records.Rollout` at the N frames (frame k is step
        k * steps_per_frame).

    Raises:
        ValueError: from :meth:`~warpskill.engine.records.SceneInputs.check`.
    """
    SceneInputs.check(inputs, steps_per_frame=steps_per_frame, fps=fps)
    dt = 1.0 / (fps * steps_per_frame)
    tensors = inputs.tensors()
    if torch.is_grad_enabled() and any(tensor.requires_grad for tensor in tensors):
        return Rollout(*_Simulate.apply(config, int(steps_per_frame), dt, *tensors))
    _, work = _launch(config, int(steps_per_frame), dt, inputs, requires_grad=False)
    _POOL.give_back(work.key, work)
    return Rollout(*_to_torch(work.frames))
