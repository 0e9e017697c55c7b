"""The per-mask losses from rendered masks' profiles in Warp kernels (``warpskill.kernels.mask_losses``), with
Torch autograd: one launch forward, two backward, in place of the ~100 small Torch ops of their reference
(``warpskill.optimizer.losses``)."""

from __future__ import annotations

import torch
import warp as wp

from warpskill.engine.warp_bridge import WorkspacePool, as_warp, copy_into, make_struct, warp_scope
from warpskill.kernels import mask_losses
from warpskill.kernels.mask_losses import EMPTY_MASS

__all__ = ["EMPTY_MASS", "LossTargets", "profile_losses"]


class LossTargets:
    """What the losses read of the target masks (N, C, H, W), as tensors of one dtype and device with their Warp
    record ``struct`` (:func:`warpskill.kernels.mask_losses.records`, made once): ``boxed`` (C,) int32,
    ``typical_mass`` (C,) [px], ``mass`` (N, C) [px], ``centroid`` (N, C, 2) (u, v) [px], ``box`` (N, C, 4)
    (u0, v0, u1, v1) [px] and ``absent`` (N, C) int32, or (0, 0) for none: ``hidden`` is whether the hidden-part
    loss applies."""

    def __init__(self, boxed, typical_mass, mass, centroid, box, absent):
        Targets, _, _ = mask_losses.records(wp.dtype_from_torch(mass.dtype))
        vec2, vec4 = (wp.types.vector(n, wp.dtype_from_torch(mass.dtype)) for n in (2, 4))
        self.tensors = [x.contiguous() for x in (boxed, typical_mass, mass, centroid, box, absent)]
        self.hidden = absent.shape[0] > 0
        with warp_scope(mass.device):
            views = [as_warp(x, t) for x, t in zip(self.tensors, (None, None, None, vec2, vec4, None))]
            self.struct = make_struct(Targets, **dict(zip(Targets.vars, views)))


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
        copy_into((work.rows, work.cols, work.overlap), (rows, cols, overlap))
        with warp_scope(rows.device):
            mask_losses.moments(work.profile, work.moments)
            mask_losses.losses(targets.struct, targets.hidden, work.profile, work.moments, work.loss_view)
        if any(ctx.needs_input_grad[:3]):
            ctx.work, ctx.targets = work, targets
        else:
            _POOL.give_back(work.key, work)
        return work.loss.clone()

    @staticmethod
    def backward(ctx, loss_grad):
        work, targets = ctx.work, ctx.targets
        work.loss_grad.copy_(loss_grad)
        torch._foreach_zero_(work.accumulated_grads)
        with warp_scope(loss_grad.device):
            mask_losses.losses(targets.struct, targets.hidden, work.profile, work.moments, work.loss_view,
                               loss_grad=work.loss_grad_view)
            mask_losses.spread(work.moments, work.moments_grad, work.profile_grad)
        grads = (work.rows_grad.clone(), work.cols_grad.clone(), work.overlap_grad.clone())
        _POOL.give_back(work.key, work)  # ctx keeps it: a second backward pass (retain_graph) reads it again
        return *grads, None


class _Workspace:
    """The buffers of :class:`_ProfileLosses` for one shape, allocated once, with the kernels' records over them
    (:func:`warpskill.kernels.mask_losses.records`, made once): the ``profile`` of the rendered masks (``rows``
    (N, C, H), ``cols`` (N, C, W), ``overlap`` (N, C)) and the ``moments`` (mass (N, C), first and second
    (N, C, 2), box (N, C, 4)), their arrays' gradients the memory of ``accumulated_grads`` (overlap, mass, first,
    second: what the loss kernel's adjoint adds into; ``moments_grad`` the moments' over them); the gradients of the
    row and column sums ``profile_grad``
    (:func:`~warpskill.kernels.mask_losses.spread`'s output); the ``loss`` (N, C) and its gradient."""

    def __init__(self, key: tuple):
        N, C, H, W, dtype, device = key
        like = {"dtype": dtype, "device": device}
        _, Profiles, Moments = mask_losses.records(wp.dtype_from_torch(dtype))
        vec2, vec4 = (wp.types.vector(n, wp.dtype_from_torch(dtype)) for n in (2, 4))
        self.key = key
        self.rows, self.cols, self.overlap = (torch.zeros(shape, **like) for shape in ((N, C, H), (N, C, W), (N, C)))
        self.rows_grad, self.cols_grad = torch.zeros_like(self.rows), torch.zeros_like(self.cols)
        moments = [torch.zeros(N, C, *shape, **like) for shape in ((), (2,), (2,), (4,))]
        self.overlap_grad, *moment_grads = (torch.zeros_like(x) for x in (self.overlap, *moments[:3]))
        self.accumulated_grads = [self.overlap_grad, *moment_grads]
        self.loss, self.loss_grad = torch.zeros(N, C, **like), torch.zeros(N, C, **like)
        with warp_scope(device):
            self.profile = make_struct(Profiles, rows=as_warp(self.rows), cols=as_warp(self.cols),
                                       overlap=as_warp(self.overlap, grad=self.overlap_grad))
            self.profile_grad = make_struct(Profiles, rows=as_warp(self.rows_grad), cols=as_warp(self.cols_grad))
            self.moments = make_struct(Moments, **{name: as_warp(x, t, grad=g) for name, x, t, g in
                                                   zip(Moments.vars, moments, (None, vec2, vec2, vec4),
                                                       (*moment_grads, None))})
            self.moments_grad = make_struct(Moments, **{name: getattr(self.moments, name).grad
                                                        for name in ("mass", "first", "second")})
            self.loss_view, self.loss_grad_view = as_warp(self.loss), as_warp(self.loss_grad)


_POOL = WorkspacePool(_Workspace)
