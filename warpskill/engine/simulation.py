"""Differentiable rollout of hand and manipulated cuboid: Torch autograd over Warp kernels.

``simulate`` integrates B scenes with the semi-implicit scheme of ``kernels/integrator.py``
(see docs/architecture.md, "Physics") and returns per-frame states as Torch tensors. The
forward pass records the Warp launches on a ``wp.Tape``; the backward pass replays it.
Float32 tensors run the float32 kernels, float64 tensors the float64 ones.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass

import torch
import warp as wp
from warpskill.kernels.integrator import Trajectory, gather_frames, rollout


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
        grasp_tau: width tau of the grasp switch sigmoid [m].
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


@dataclass
class Rollout:
    """Per-frame states of B scenes over N frames (Torch tensors, differentiable).

    Attributes:
        hand_pos: (B, N, 3) hand tip position [m].
        hand_rot: (B, N, 3, 3) hand rotation (hand frame to world).
        grasp: (B, N) grasp signal g.
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


# argument name -> (shape with symbolic sizes, Warp value type: "vec3", "mat33" or "scalar")
_INPUTS = {
    "hand_pos0": (("B", 3), "vec3"),
    "hand_rot0": (("B", 3, 3), "mat33"),
    "grasp0": (("B",), "scalar"),
    "hand_vel": (("B", "S", 7), "scalar"),
    "object_pos0": (("B", 3), "vec3"),
    "object_rot0": (("B", 3, 3), "mat33"),
    "object_size": (("B", 3), "vec3"),
    "static_pos": (("B", "K", 3), "vec3"),
    "static_rot": (("B", "K", 3, 3), "mat33"),
    "static_size": (("B", "K", 3), "vec3"),
}


def _validate(tensors: dict[str, torch.Tensor]) -> dict[str, int]:
    """Check types, shapes, dtype, device and finiteness; return the symbolic sizes."""
    sizes: dict[str, int] = {}
    first = tensors["hand_pos0"]
    for name, tensor in tensors.items():
        if not isinstance(tensor, torch.Tensor):
            raise ValueError(f"{name} must be a torch.Tensor, got {type(tensor).__name__}")
        if tensor.dtype not in (torch.float32, torch.float64):
            raise ValueError(f"{name} must be float32 or float64, got {tensor.dtype}")
        if tensor.dtype != first.dtype:
            raise ValueError(f"{name} has dtype {tensor.dtype}, but hand_pos0 has {first.dtype}")
        if tensor.device != first.device:
            raise ValueError(f"{name} is on {tensor.device}, but hand_pos0 is on {first.device}")
        shape, _ = _INPUTS[name]
        expected = tuple(sizes.get(dim, "?") if isinstance(dim, str) else dim for dim in shape)
        if tensor.ndim != len(shape):
            raise ValueError(f"{name} must have shape {shape}, got {tuple(tensor.shape)}")
        for dim, size in zip(shape, tensor.shape):
            if isinstance(dim, str):
                dim = sizes.setdefault(dim, size)
            if dim != size:
                raise ValueError(f"{name} must have shape {expected}, got {tuple(tensor.shape)}")
        if not torch.isfinite(tensor).all():
            raise ValueError(f"{name} contains NaN or infinite values")
    if not (tensors["object_size"] > 0).all():
        raise ValueError("object_size must be positive")
    if not (tensors["static_size"] > 0).all():
        raise ValueError("static_size must be positive")
    return sizes


def _launch(config: PhysicsConfig, steps_per_frame: int, dt: float, tensors: tuple, requires_grad: bool):
    """Run the rollout on Warp views of ``tensors``; returns the tape, the input arrays and the
    per-frame :class:`Trajectory`. Launches are recorded on the tape if ``requires_grad``."""
    wp.init()
    device = tensors[0].device
    scalar = wp.float64 if tensors[0].dtype == torch.float64 else wp.float32
    value_types = {"vec3": wp.types.vector(3, scalar), "mat33": wp.types.matrix((3, 3), scalar), "scalar": scalar}
    kinds = [kind for _, kind in _INPUTS.values()]
    inputs = [_as_warp(tensor, value_types[kind], requires_grad) for tensor, kind in zip(tensors, kinds)]
    hand_pos0, hand_rot0, grasp0, hand_vel, object_pos0, object_rot0, *geometry = inputs
    num_scenes, num_steps = hand_vel.shape[0], hand_vel.shape[1]
    warp_device = wp.device_from_torch(device)
    steps = Trajectory.zeros(num_scenes, num_steps + 1, scalar, warp_device, requires_grad)
    frames = Trajectory.zeros(num_scenes, num_steps // steps_per_frame + 1, scalar, warp_device, requires_grad)
    tape = wp.Tape()
    with _warp_scope(device), tape if requires_grad else contextlib.nullcontext():
        rollout(config, dt, *geometry, hand_pos0, hand_rot0, grasp0, hand_vel, object_pos0, object_rot0, steps)
        gather_frames(steps_per_frame, steps, frames)
    return tape, inputs, frames


def _as_warp(tensor: torch.Tensor, dtype, requires_grad: bool) -> wp.array:
    """Zero-copy Warp view of ``tensor`` with a Warp-owned gradient buffer."""
    if tensor.numel() == 0:  # Torch may give empty tensors zero strides, which Warp refuses
        shape = tensor.shape[: tensor.ndim - len(getattr(dtype, "_shape_", ()))]
        device = wp.device_from_torch(tensor.device)
        return wp.zeros(shape, dtype=dtype, device=device, requires_grad=requires_grad)
    return wp.from_torch(tensor.detach().contiguous(), dtype=dtype, requires_grad=requires_grad)


def _to_torch(frames: Trajectory) -> tuple[torch.Tensor, ...]:
    return tuple(wp.to_torch(array, requires_grad=False) for array in frames.arrays())


class _Simulate(torch.autograd.Function):
    """Autograd bridge: forward records the Warp rollout on a tape, backward replays it."""

    @staticmethod
    def forward(ctx, config: PhysicsConfig, steps_per_frame: int, dt: float, *tensors: torch.Tensor):
        ctx.set_materialize_grads(False)  # unused outputs seed nothing
        ctx.device = tensors[0].device
        ctx.tape, ctx.inputs, ctx.frames = _launch(config, steps_per_frame, dt, tensors, requires_grad=True)
        return _to_torch(ctx.frames)

    @staticmethod
    def backward(ctx, *grad_outputs: torch.Tensor):
        grads = {
            array: wp.from_torch(grad.contiguous(), dtype=array.dtype, requires_grad=False)
            for array, grad in zip(ctx.frames.arrays(), grad_outputs)
            if grad is not None
        }
        with _warp_scope(ctx.device):
            ctx.tape.backward(grads=grads)  # copies the seeds into the frames' own .grad buffers
            input_grads = [
                wp.to_torch(array.grad, requires_grad=False).clone() if needed else None
                for array, needed in zip(ctx.inputs, ctx.needs_input_grad[3:])
            ]
            ctx.tape.zero()
        return (None, None, None, *input_grads)


@contextlib.contextmanager
def _warp_scope(device: torch.device):
    """Run Warp on the Torch device: its current stream on CUDA; on the CPU with denormal
    floats flushed to zero (the mode is restored after). Velocities decaying while an object
    rests or is held pass through float32's denormal range, where CPU arithmetic is about 100
    times slower."""
    if device.type == "cuda":
        with wp.ScopedStream(wp.stream_from_torch(device)):
            yield
        return
    flushing = torch.tensor(1e-40, dtype=torch.float32).item() == 0.0
    with wp.ScopedDevice("cpu"):
        if flushing or not torch.set_flush_denormal(True):
            yield
            return
        try:
            yield
        finally:
            torch.set_flush_denormal(False)


def simulate(
    hand_pos0: torch.Tensor,
    hand_rot0: torch.Tensor,
    grasp0: torch.Tensor,
    hand_vel: torch.Tensor,
    object_pos0: torch.Tensor,
    object_rot0: torch.Tensor,
    object_size: torch.Tensor,
    static_pos: torch.Tensor,
    static_rot: torch.Tensor,
    static_size: torch.Tensor,
    *,
    steps_per_frame: int,
    fps: float,
    config: PhysicsConfig = PhysicsConfig(),
) -> Rollout:
    """Roll out B scenes of hand, manipulated cuboid and K static cuboids.

    The step is dt = 1 / (fps * steps_per_frame) [s]; the object starts at rest. All tensors
    share one dtype (float32 or float64) and device; gradients reach every input.

    Args:
        hand_pos0: (B, 3) initial hand tip position [m].
        hand_rot0: (B, 3, 3) initial hand rotation.
        grasp0: (B,) initial grasp signal.
        hand_vel: (B, S, 7) per-step hand velocities: linear [m/s] (3), angular [rad/s] (3),
            grasp rate [1/s] (1); S = (N - 1) * steps_per_frame, N >= 2 frames.
        object_pos0: (B, 3) initial object centre [m].
        object_rot0: (B, 3, 3) initial object rotation.
        object_size: (B, 3) full edge lengths of the object [m].
        static_pos: (B, K, 3) static cuboid centres [m]; K may be 0.
        static_rot: (B, K, 3, 3) static cuboid rotations.
        static_size: (B, K, 3) static cuboid edge lengths [m].
        steps_per_frame: integration steps per frame (see :func:`substeps_per_frame`).
        fps: frame rate [1/s].
        config: physics constants.

    Returns:
        The :class:`Rollout` at the N frames (frame k is step k * steps_per_frame).
    """
    tensors = {
        "hand_pos0": hand_pos0,
        "hand_rot0": hand_rot0,
        "grasp0": grasp0,
        "hand_vel": hand_vel,
        "object_pos0": object_pos0,
        "object_rot0": object_rot0,
        "object_size": object_size,
        "static_pos": static_pos,
        "static_rot": static_rot,
        "static_size": static_size,
    }
    sizes = _validate(tensors)
    if steps_per_frame < 1:
        raise ValueError(f"steps_per_frame must be >= 1, got {steps_per_frame}")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    if sizes["S"] < steps_per_frame or sizes["S"] % steps_per_frame:
        raise ValueError(
            f"hand_vel must have (N - 1) * steps_per_frame steps with N >= 2, got {sizes['S']} steps "
            f"for steps_per_frame={steps_per_frame}"
        )
    dt = 1.0 / (fps * steps_per_frame)
    if torch.is_grad_enabled() and any(tensor.requires_grad for tensor in tensors.values()):
        return Rollout(*_Simulate.apply(config, int(steps_per_frame), dt, *tensors.values()))
    _, _, frames = _launch(config, int(steps_per_frame), dt, tuple(tensors.values()), requires_grad=False)
    return Rollout(*_to_torch(frames))
