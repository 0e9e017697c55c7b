"""The per-mask losses from rendered masks' profiles in Warp kernels (``warpskill.kernels.mask_losses``), with
Torch autograd: one launch forward, two backward, in place of the ~100 small Torch ops of their reference
(``warpskill.optimizer.losses``)."""

from __future__ import annotations

import torch
import warp as wp

from warpskill.engine.warp_bridge import WorkspacePool, as_warp, warp_scope
from warpskill.kernels import mask_losses
from warpskill.kernels.mask_losses import EMPTY_MASS

__all__ = ["EMPTY_MASS", "LossTargets", "profile_losses"]


class LossTargets:
    """What the losses read of the target masks (N, C, H, W), as tensors of one dtype and device with their Warp
    views (made once): ``boxed`` (C,) int32, ``typical_mass`` (C,) [px], ``mass`` (N, C) [px], ``centroid``
    (N, C, 2) (u, v) [px], ``box`` (N, C, 4) (u0, v0, u1, v1) [px] and ``absent`` (N, C) int32 ((0, 0): none)."""

    def __init__(self, boxed, typical_mass, mass, centroid, box, absent):
        vec2, vec4 = (wp.types.vector(n, wp.dtype_from_torch(mass.dtype)) for n in (2, 4))
        self.tensors = [x.contiguous() for x in (boxed, typical_mass, mass, centroid, box, absent)]
        with warp_scope(mass.device):
            self.views = [as_warp(x, t) for x, t in zip(self.tensors, (None, None, None, vec2, vec4, None))]


def profile_losses(rows: torch.Tensor, cols: torch.Tensor, overlap: torch.Tensor, targets: LossTargets) -> torch.Tensor:
    """Loss per mask (N, C) of rendered masks whose row sums are ``rows`` (N, C, H), column sums ``cols``
    (N, C, W) and overlaps with the targets ``overlap`` (N, C) [px]: the hidden-part loss where ``targets.absent``,
    else the box dIoU on the channels ``targets.boxed``, else the dIoU (:mod:`warpskill.kernels.mask_losses`);
    differentiable in the three."""
    return _ProfileLosses.apply(rows, cols, overlap, targets)


class _ProfileLosses(torch.autograd.Function):
    """:func:`profile_losses`; the buffers come from a :class:`_Workspace` of the shape, held from forward to
    backward."""

    @staticmethod
    def forward(ctx, rows, cols, overlap, targets):
        wp.init()  # no-op once Warp is up
        N, C, H = rows.shape
        work = _POOL.take((N, C, H, cols.shape[2], rows.dtype, rows.device))
        for buffer, tensor in zip((work.rows, work.cols, work.overlap), (rows, cols, overlap)):
            buffer.copy_(tensor.detach())
        with warp_scope(rows.device):
            mask_losses.moments(*work.views["profile"], *work.views["moments"])
            mask_losses.losses(targets.views[:2], targets.views[2:], work.views["rendered"], work.views["loss"])
        if any(ctx.needs_input_grad[:3]):
            ctx.work, ctx.targets = work, targets
        else:
            _POOL.give_back(work.key, work)
        return work.loss.clone()

    @staticmethod
    def backward(ctx, loss_grad):
        work, targets = ctx.work, ctx.targets
        work.loss_grad.copy_(loss_grad)
        for grad in work.rendered_grads:
            grad.zero_()
        with warp_scope(loss_grad.device):
            mask_losses.losses(targets.views[:2], targets.views[2:], work.views["rendered"], work.views["loss"],
                               work.views["rendered_grads"], work.views["loss_grad"])
            mask_losses.spread(*work.views["rendered"][1:3], work.views["rendered_grads"][1:4],
                               *work.views["profile_grads"])
        grads = (work.rows_grad.clone(), work.cols_grad.clone(), work.rendered_grads[0].clone())
        _POOL.give_back(work.key, work)  # ctx keeps it: a second backward pass (retain_graph) reads it again
        return *grads, None


class _Workspace:
    """The buffers of :class:`_ProfileLosses` for one shape, allocated once, with their Warp views (made once):
    the profile ``rows`` (N, C, H), ``cols`` (N, C, W), ``overlap`` (N, C); the moments mass (N, C), first and
    second (N, C, 2), box (N, C, 4); the ``loss`` (N, C); and the gradients of all but the box."""

    def __init__(self, key: tuple):
        N, C, H, W, dtype, device = key
        like = {"dtype": dtype, "device": device}
        self.key = key
        self.rows, self.cols, self.overlap = (torch.zeros(shape, **like) for shape in ((N, C, H), (N, C, W), (N, C)))
        self.rows_grad, self.cols_grad = torch.zeros_like(self.rows), torch.zeros_like(self.cols)
        shapes = ((N, C), (N, C), (N, C, 2), (N, C, 2))  # overlap, mass, first, second
        moments = [torch.zeros(shape, **like) for shape in shapes[1:]] + [torch.zeros(N, C, 4, **like)]
        self.rendered_grads = [torch.zeros(shape, **like) for shape in shapes]
        self.loss, self.loss_grad = torch.zeros(N, C, **like), torch.zeros(N, C, **like)
        vec2, vec4 = (wp.types.vector(n, wp.dtype_from_torch(dtype)) for n in (2, 4))
        with warp_scope(device):
            moment_views = [as_warp(x, t) for x, t in zip(moments, (None, vec2, vec2, vec4))]
            self.views = {
                "profile": [as_warp(self.rows), as_warp(self.cols)],
                "moments": moment_views,
                "rendered": [as_warp(self.overlap), *moment_views],
                "rendered_grads": [as_warp(x, t) for x, t in zip(self.rendered_grads, (None, None, vec2, vec2))],
                "profile_grads": [as_warp(self.rows_grad), as_warp(self.cols_grad)],
                "loss": as_warp(self.loss),
                "loss_grad": as_warp(self.loss_grad),
            }


_POOL = WorkspacePool(_Workspace)
