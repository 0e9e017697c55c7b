"""Mask losses: the distance-IoU (dIoU) of the paper, for soft rendered silhouettes."""

from __future__ import annotations

import torch

_EMPTY_MASS = 1e-3  # [px]: a mask with less total mass than this counts as empty


class MaskTargets:
    """Target masks (..., H, W) in [0, 1] with their moments computed once, for repeated losses."""

    def __init__(self, masks: torch.Tensor):
        self.masks = masks
        with torch.no_grad():
            self.moments = _MaskMoments(masks)


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
    if rendered.shape != targets.masks.shape:
        raise ValueError(
            f"rendered {tuple(rendered.shape)} and target {tuple(targets.masks.shape)} masks differ in shape"
        )
    intersection = (rendered * targets.masks).sum((-2, -1))
    r, t = _MaskMoments(rendered), targets.moments
    iou = intersection / (r.mass + t.mass - intersection).clamp_min(_EMPTY_MASS)
    lo = torch.minimum(r.box_min, t.box_min)
    hi = torch.maximum(r.box_max, t.box_max)
    diag2 = ((hi - lo) ** 2).sum(-1).clamp_min(1.0)
    distance = ((r.centroid - t.centroid) ** 2).sum(-1) / diag2

    valid = t.mass > _EMPTY_MASS
    rendered_empty = r.mass <= _EMPTY_MASS
    loss = torch.where(rendered_empty, torch.full_like(iou, 2.0), 1.0 - iou + distance.clamp_max(1.0))
    return torch.where(valid, loss, torch.zeros_like(loss)), valid


class _MaskMoments:
    """Mass [px], centroid (u, v) [px] and box corners of masks (..., H, W), from row and column sums."""

    def __init__(self, masks: torch.Tensor):
        H, W = masks.shape[-2:]
        v = torch.arange(H, dtype=masks.dtype, device=masks.device) + 0.5
        u = torch.arange(W, dtype=masks.dtype, device=masks.device) + 0.5
        rows = masks.sum(-1)  # (..., H)
        cols = masks.sum(-2)  # (..., W)
        self.mass = rows.sum(-1)
        denominator = self.mass.clamp_min(_EMPTY_MASS)
        self.centroid = torch.stack([(cols * u).sum(-1) / denominator, (rows * v).sum(-1) / denominator], -1)
        inf = torch.tensor(float("inf"), dtype=masks.dtype, device=masks.device)
        in_col, in_row = cols.detach() >= 0.5, rows.detach() >= 0.5
        # An empty mask gets an inverted box (+inf, -inf): it never widens the union box.
        self.box_min = torch.stack(
            [torch.where(in_col, u - 0.5, inf).amin(-1), torch.where(in_row, v - 0.5, inf).amin(-1)], -1
        )
        self.box_max = torch.stack(
            [torch.where(in_col, u + 0.5, -inf).amax(-1), torch.where(in_row, v + 0.5, -inf).amax(-1)], -1
        )
