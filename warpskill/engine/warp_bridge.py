"""Torch -> Warp: the one array wrapper and the one launch scope of the engine's autograd bridges
(:mod:`warpskill.engine.simulation`, :mod:`warpskill.engine.rendering`)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence

import numpy as np
import torch
import warp as wp

from warpskill.warp_log import configure_warp_log

configure_warp_log()  # quiet unless asked for (warpskill --verbose), before any kernel loads

_DENORMAL = 1e-40  # a float32 denormal


def as_warp(
    tensor: torch.Tensor, dtype=None, requires_grad: bool = False, grad: torch.Tensor | None = None
) -> wp.array:
    """Zero-copy Warp view of ``tensor`` (detached), with a Warp-owned gradient buffer if
    ``requires_grad``, or with the view of ``grad`` as its gradient.

    A non-contiguous tensor is copied first, so only contiguous ones may be written through
    the view. An empty tensor gives a fresh empty array (Torch may give empty tensors zero
    strides, which Warp refuses).

    Args:
        tensor: the Torch tensor; its trailing dimensions hold ``dtype``'s vector or matrix.
        dtype: Warp value type (e.g. ``wp.vec3``); None: the scalar type of ``tensor``.
        requires_grad: give the array a gradient buffer.
        grad: a contiguous tensor of ``tensor``'s shape and dtype, the gradient's memory (what a kernel's
            adjoint adds into through a Warp struct: its arrays' own gradients).
    """
    if tensor.numel() == 0:
        if dtype is None:
            dtype = wp.dtype_from_torch(tensor.dtype)
        shape = tensor.shape[: tensor.ndim - len(getattr(dtype, "_shape_", ()))]
        device = wp.device_from_torch(tensor.device)
        array = wp.zeros(shape, dtype=dtype, device=device, requires_grad=requires_grad)
    else:
        array = wp.from_torch(tensor.detach().contiguous(), dtype=dtype, requires_grad=requires_grad)
    if grad is not None:
        array.grad = as_warp(grad, dtype)
    return array


def make_struct(kind, **fields):
    """An instance of the Warp struct type ``kind`` with ``fields`` set (the others null or zero)."""
    record = kind()
    for name, value in fields.items():
        setattr(record, name, value)
    return record


@torch.no_grad()
def copy_into(buffers: Sequence[torch.Tensor], tensors: Sequence[torch.Tensor]) -> None:
    """Copy each of ``tensors`` into the buffer of the same shape (detached), in one multi-tensor op."""
    torch._foreach_copy_(list(buffers), list(tensors))


@contextlib.contextmanager
def warp_scope(device: torch.device) -> Iterator[None]:
    """Run Warp on the Torch device: its current stream on CUDA; on the CPU with denormal
    floats flushed to zero (the mode is restored after). Velocities decaying while an object
    rests or is held pass through float32's denormal range, where CPU arithmetic is about 100
    times slower. (The raster reuses its image-sized buffers, :class:`~warpskill.engine.rendering._Workspace`,
    so no allocator setting is needed.)"""
    if device.type == "cuda":
        with wp.ScopedStream(wp.stream_from_torch(device)):
            yield
        return
    flushing = np.float32(_DENORMAL) == 0.0  # this thread already flushes denormals to zero
    with wp.ScopedDevice("cpu"):
        if flushing or not torch.set_flush_denormal(True):
            yield
            return
        try:
            yield
        finally:
            torch.set_flush_denormal(False)


class WorkspacePool:
    """Engine buffers by shape, allocated once and reused: :meth:`take` hands out a free workspace
    of a shape (made with ``make(key)`` when none is free), :meth:`give_back` returns it once the
    call that took it is done (its backward pass has run), so calls still pending never share
    one. Only the ``kept`` latest shapes are kept."""

    def __init__(self, make, kept: int = 4):
        self.make, self.kept = make, kept
        self.free: dict[tuple, list] = {}

    def take(self, key: tuple):
        """A free workspace of shape ``key`` (a new one if none is free)."""
        free = self.free.pop(key, [])
        self.free[key] = free  # the latest shape last: the pool forgets the oldest
        while len(self.free) > self.kept:
            del self.free[next(iter(self.free))]
        return free.pop() if free else self.make(key)

    def give_back(self, key: tuple, workspace) -> None:
        """Return ``workspace`` of shape ``key`` (kept while its shape is among the latest); one
        given back twice (a graph's second backward pass, ``retain_graph``) is listed once."""
        free = self.free.get(key)
        if free is not None and not any(w is workspace for w in free):
            free.append(workspace)
