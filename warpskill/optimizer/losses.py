"""Mask losses: the distance-IoU (dIoU) of the paper, for soft rendered silhouettes."""

from __future__ import annotations

from functools import cached_property

import torch

from warpskill.engine.mask_losses import EMPTY_MASS as _EMPTY_MASS  # [px]: a mask with less mass counts as empty
from warpskill.engine.mask_losses import LossTargets, profile_losses


class MaskTargets:
    """Target masks (..., C, H, W) in [0, 1] with their moments computed once, for repeated losses.

    ``boxed``: (C,) bool, channels whose masks are drawn from boxes (the shape inside a box
    annotation): :func:`box_loss` compares only their boxes. ``absent``: (N, C) bool, frames
    in which a channel's part is known to be out of sight (hidden behind another part or out
    of the image), not merely unseen: :func:`hidden_loss` asks its rendering to vanish there.
    """

    def __init__(self, masks: torch.Tensor, boxed: torch.Tensor | None = None, absent: torch.Tensor | None = None):
        self.masks = masks.contiguous()  # read as is by the raster kernels, every iteration
        self.boxed = boxed
        self.absent = absent
        with torch.no_grad():
            self.moments = _MaskMoments.of(masks)
            if absent is not None:  # (N, C) masks
                mass = self.moments.mass
                seen = mass > _EMPTY_MASS
                #: (C,) [px] each channel's median mass where it is seen: the scale of a hidden rendering.
                self.typical_mass = torch.stack([
                    mass[seen[:, c], c].median() if seen[:, c].any() else mass.new_ones(())
                    for c in range(mass.shape[1])
                ])
        self._loss_targets: dict[torch.dtype, LossTargets] = {}

    def loss_targets(self, dtype: torch.dtype) -> LossTargets:
        """What the loss kernels read of these targets, in ``dtype`` (made once per dtype)."""
        if dtype not in self._loss_targets:
            m = self.moments
            C = m.mass.shape[-1]
            i32 = {"dtype": torch.int32, "device": m.mass.device}
            boxed = self.boxed.to(**i32) if self.boxed is not None else torch.zeros(C, **i32)
            absent = self.absent.to(**i32) if self.absent is not None else torch.zeros(0, 0, **i32)
            typical = self.typical_mass if self.absent is not None else torch.ones(C, device=m.mass.device)
            self._loss_targets[dtype] = LossTargets(
                boxed, typical.to(dtype), m.mass.to(dtype), m.centroid.to(dtype),
                torch.cat([m.box_min, m.box_max], -1).to(dtype), absent)
        return self._loss_targets[dtype]


def diou_loss(rendered: torch.Tensor, target: torch.Tensor | MaskTargets) -> tuple[torch.Tensor, torch.Tensor]:
    """Distance-IoU loss between soft rendered masks and target masks, per mask.

    ``dIoU = 1 - IoU + |c_r - c_t|^2 / diag^2`` where ``c_r``, ``c_t`` are the mask
    centroids [px] and ``diag`` the diagonal of the smallest box enclosing both masks (a
    mask's box spans the rows and columns holding at least half a pixel of it; the box
    carries no gradient). Every statistic comes from three reductions of each mask stack:
    row sums, column sums and the intersection.

    Empty masks, as the paper treats them: where the *target* is empty (the object is
    occluded or out of view) the frame carries no perceptual term, and is reported as
    invalid; where only the *rendering* is empty the loss is its maximum, 2.

    Args:
        rendered: (..., H, W) soft masks in [0, 1].
        target: (..., H, W) masks in [0, 1] (area-averaged to the working resolution), or
            :class:`MaskTargets` holding them (faster when the same targets recur).

    Returns:
        ``(loss, valid)``: (...) dIoU per mask (0 where invalid) and the (...) bool mask
        of entries whose target is not empty.
    """
    targets = target if isinstance(target, MaskTargets) else MaskTargets(target.to(rendered))
    profile = MaskProfile.of(rendered, targets)
    return _diou(profile, targets), targets.moments.mass > _EMPTY_MASS


def hidden_loss(rendered: torch.Tensor, targets: MaskTargets) -> torch.Tensor:
    """Per mask (N, C): the rendered mass [px] over the channel's typical mass, at most 1.

    Where a part is known to be out of sight (``targets.absent``), a rendering that shows
    it is wrong: it should be occluded or outside the image. An empty target elsewhere says
    nothing (:func:`diou_loss` gives it no term).
    """
    return _hidden(MaskProfile.of(rendered, targets), targets)


def box_loss(rendered: torch.Tensor, targets: MaskTargets) -> torch.Tensor:
    """Distance-IoU of boxes, per mask (...): the target mask's box against the box that a
    uniform filling would give the rendered mask's moments.

    For a target drawn from a box annotation only the box is known: an ellipse inscribed in
    the box of a slanted forearm is a wide blob that the thin hand cylinder could only fill
    from close by. A rendered silhouette spread uniformly over [a, b] along an axis has the
    mean (a + b) / 2 and the standard deviation (b - a) / sqrt(12), whatever its shape, so
    ``mean +- sqrt(3) std`` per axis is its box, with gradients. Frames with an empty target
    count 0; an empty rendering counts 2, as in :func:`diou_loss`.
    """
    return _box(MaskProfile.of(rendered, targets), targets)


def masks_loss(rendered: torch.Tensor | MaskProfile, targets: MaskTargets) -> torch.Tensor:
    """Per mask (N, C): :func:`diou_loss`, :func:`box_loss` on the channels drawn from boxes
    (``targets.boxed``) and :func:`hidden_loss` where a part is known to be out of sight
    (``targets.absent``), from the rendered masks' profile (given, or from one pass over them),
    in Warp kernels (:func:`warpskill.engine.mask_losses.profile_losses`; the functions here are
    their reference)."""
    profile = rendered if isinstance(rendered, MaskProfile) else MaskProfile.of(rendered, targets)
    rows = profile.rows
    return profile_losses(rows, profile.cols, profile.overlap, targets.loss_targets(rows.dtype))


class MaskProfile:
    """What every mask loss reads of rendered masks (..., H, W): row sums (..., H), column
    sums (..., W) and the overlap (...) with the targets, and the moments of
    :class:`_MaskMoments` from them. The raster can give them without forming the masks
    (:func:`warpskill.engine.rendering.silhouette_profiles`); :meth:`of` takes them from masks."""

    def __init__(self, rows: torch.Tensor, cols: torch.Tensor, overlap: torch.Tensor):
        self.rows, self.cols, self.overlap = rows, cols, overlap

    @cached_property
    def moments(self) -> "_MaskMoments":
        """The rendered masks' :class:`_MaskMoments` (made on first use)."""
        return _MaskMoments(self.rows, self.cols)

    @classmethod
    def of(cls, rendered: torch.Tensor, targets: MaskTargets) -> "MaskProfile":
        """The profile of masks ``rendered`` (..., H, W) against ``targets``, from one pass (:class:`_Profile`)."""
        if rendered.shape != targets.masks.shape:
            raise ValueError(
                f"rendered {tuple(rendered.shape)} and target {tuple(targets.masks.shape)} masks differ in shape"
            )
        return cls(*_Profile.apply(rendered, targets.masks.to(rendered)))


class _Profile(torch.autograd.Function):
    """(rows, cols, overlap) of masks (..., H, W) against fixed targets; the gradient is the
    broadcast ``g_rows[:, None] + g_cols[None, :] + g_overlap * targets``, one image (the
    separate Torch reductions would each write an image of gradients and sum them)."""

    @staticmethod
    def forward(ctx, masks: torch.Tensor, targets: torch.Tensor):
        ctx.save_for_backward(targets)
        overlap = torch.linalg.vecdot(masks.flatten(-2), targets.flatten(-2))
        return masks.sum(-1), masks.sum(-2), overlap

    @staticmethod
    def backward(ctx, g_rows: torch.Tensor, g_cols: torch.Tensor, g_overlap: torch.Tensor):
        (targets,) = ctx.saved_tensors
        grad = g_rows.unsqueeze(-1) + g_cols.unsqueeze(-2)
        return torch.addcmul(grad, g_overlap[..., None, None], targets), None


def _diou(profile: MaskProfile, targets: MaskTargets) -> torch.Tensor:
    """:func:`diou_loss`'s per-mask loss from the rendered masks' profile."""
    r, t = profile.moments, targets.moments
    intersection = profile.overlap
    iou = intersection / (r.mass + t.mass - intersection).clamp_min(_EMPTY_MASS)
    lo = torch.minimum(r.box_min, t.box_min)
    hi = torch.maximum(r.box_max, t.box_max)
    diag2 = ((hi - lo) ** 2).sum(-1).clamp_min(1.0)
    distance = ((r.centroid - t.centroid) ** 2).sum(-1) / diag2
    valid = t.mass > _EMPTY_MASS
    rendered_empty = r.mass <= _EMPTY_MASS
    loss = torch.where(rendered_empty, torch.full_like(iou, 2.0), 1.0 - iou + distance.clamp_max(1.0))
    return torch.where(valid, loss, torch.zeros_like(loss))


def _hidden(profile: MaskProfile, targets: MaskTargets) -> torch.Tensor:
    """:func:`hidden_loss` from the rendered masks' profile."""
    return (profile.moments.mass / targets.typical_mass.clamp_min(1.0)).clamp_max(1.0)


def _box(profile: MaskProfile, targets: MaskTargets) -> torch.Tensor:
    """:func:`box_loss` from the rendered masks' profile."""
    t, r = targets.moments, profile.moments
    std = r.spread()
    r_min, r_max = r.centroid - 3**0.5 * std, r.centroid + 3**0.5 * std
    overlap = (torch.minimum(r_max, t.box_max) - torch.maximum(r_min, t.box_min)).clamp_min(0.0).prod(-1)
    area_r = (r_max - r_min).prod(-1)
    area_t = (t.box_max - t.box_min).clamp_min(0.0).prod(-1)
    iou = overlap / (area_r + area_t - overlap).clamp_min(_EMPTY_MASS)
    centre = torch.nan_to_num(0.5 * (t.box_min + t.box_max))  # an empty target's inverted box: NaN
    hull = (torch.maximum(r_max, t.box_max) - torch.minimum(r_min, t.box_min)).square().sum(-1).clamp_min(1.0)
    distance = (r.centroid - centre).square().sum(-1) / hull
    valid = t.mass > _EMPTY_MASS
    loss = torch.where(r.mass <= _EMPTY_MASS, torch.full_like(iou, 2.0), 1.0 - iou + distance.clamp_max(1.0))
    return torch.where(valid, loss, torch.zeros_like(loss))


class _MaskMoments:
    """Mass [px], centroid (u, v) [px] and box corners of masks (..., H, W), from their row
    sums (..., H) and column sums (..., W)."""

    def __init__(self, rows: torch.Tensor, cols: torch.Tensor):
        H, W = rows.shape[-1], cols.shape[-1]
        self.rows, self.cols = rows, cols
        self.v = torch.arange(H, dtype=rows.dtype, device=rows.device) + 0.5
        self.u = torch.arange(W, dtype=rows.dtype, device=rows.device) + 0.5
        self.mass = rows.sum(-1)
        self.denominator = self.mass.clamp_min(_EMPTY_MASS)
        self.centroid = torch.stack(
            [(cols * self.u).sum(-1) / self.denominator, (rows * self.v).sum(-1) / self.denominator], -1
        )
        inf = torch.tensor(float("inf"), dtype=rows.dtype, device=rows.device)
        in_col, in_row = cols.detach() >= 0.5, rows.detach() >= 0.5
        # An empty mask gets an inverted box (+inf, -inf): it never widens the union box.
        self.box_min = torch.stack(
            [torch.where(in_col, self.u - 0.5, inf).amin(-1), torch.where(in_row, self.v - 0.5, inf).amin(-1)], -1
        )
        self.box_max = torch.stack(
            [torch.where(in_col, self.u + 0.5, -inf).amax(-1), torch.where(in_row, self.v + 0.5, -inf).amax(-1)], -1
        )

    @classmethod
    def of(cls, masks: torch.Tensor) -> "_MaskMoments":
        """The moments of masks (..., H, W)."""
        return cls(masks.sum(-1), masks.sum(-2))

    def spread(self) -> torch.Tensor:
        """Standard deviation (u, v) [px] along each axis (..., 2); a one-pixel mask is 1 px wide."""
        var_u = (self.cols * (self.u - self.centroid[..., :1]).square()).sum(-1) / self.denominator
        var_v = (self.rows * (self.v - self.centroid[..., 1:]).square()).sum(-1) / self.denominator
        return (torch.stack([var_u, var_v], -1) + 1.0 / 12.0).sqrt()
