"""Mask losses: the distance-IoU (dIoU) of the paper, for soft rendered silhouettes."""

from __future__ import annotations

import torch

_EMPTY_MASS = 1e-3  # [px]: a mask with less total mass than this counts as empty


class MaskTargets:
    """Target masks (..., C, H, W) in [0, 1] with their moments computed once, for repeated losses.

    ``boxed``: (C,) bool, channels whose masks are drawn from boxes (the shape inside a box
    annotation): :func:`box_loss` compares only their boxes. ``absent``: (N, C) bool, frames
    in which a channel's part is known to be out of sight (hidden behind another part or out
    of the image), not merely unseen: :func:`hidden_loss` asks its rendering to vanish there.
    """

    def __init__(self, masks: torch.Tensor, boxed: torch.Tensor | None = None, absent: torch.Tensor | None = None):
        self.masks = masks
        self.boxed = boxed
        self.absent = absent
        with torch.no_grad():
            self.moments = _MaskMoments(masks)
            if absent is not None:  # (N, C) masks
                mass = self.moments.mass
                seen = mass > _EMPTY_MASS
                #: (C,) [px] each channel's median mass where it is seen: the scale of a hidden rendering.
                self.typical_mass = torch.stack([
                    mass[seen[:, c], c].median() if seen[:, c].any() else mass.new_ones(())
                    for c in range(mass.shape[1])
                ])


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


def hidden_loss(rendered: torch.Tensor, targets: MaskTargets) -> torch.Tensor:
    """Per mask (N, C): the rendered mass [px] over the channel's typical mass, at most 1.

    Where a part is known to be out of sight (``targets.absent``), a rendering that shows
    it is wrong: it should be occluded or outside the image. An empty target elsewhere says
    nothing (:func:`diou_loss` gives it no term).
    """
    mass = rendered.sum((-2, -1))
    return (mass / targets.typical_mass.clamp_min(1.0)).clamp_max(1.0)


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
    t = targets.moments
    r = _MaskMoments(rendered, spread=True)
    r_min, r_max = r.centroid - 3**0.5 * r.std, r.centroid + 3**0.5 * r.std
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
    """Mass [px], centroid (u, v) [px] and box corners of masks (..., H, W), from row and column
    sums; with ``spread`` also the standard deviation (u, v) [px] along each axis."""

    def __init__(self, masks: torch.Tensor, *, spread: bool = False):
        H, W = masks.shape[-2:]
        v = torch.arange(H, dtype=masks.dtype, device=masks.device) + 0.5
        u = torch.arange(W, dtype=masks.dtype, device=masks.device) + 0.5
        rows = masks.sum(-1)  # (..., H)
        cols = masks.sum(-2)  # (..., W)
        self.mass = rows.sum(-1)
        denominator = self.mass.clamp_min(_EMPTY_MASS)
        self.centroid = torch.stack([(cols * u).sum(-1) / denominator, (rows * v).sum(-1) / denominator], -1)
        if spread:
            var_u = (cols * (u - self.centroid[..., :1]).square()).sum(-1) / denominator
            var_v = (rows * (v - self.centroid[..., 1:]).square()).sum(-1) / denominator
            self.std = (torch.stack([var_u, var_v], -1) + 1.0 / 12.0).sqrt()  # a one-pixel mask is 1 px wide
        inf = torch.tensor(float("inf"), dtype=masks.dtype, device=masks.device)
        in_col, in_row = cols.detach() >= 0.5, rows.detach() >= 0.5
        # An empty mask gets an inverted box (+inf, -inf): it never widens the union box.
        self.box_min = torch.stack(
            [torch.where(in_col, u - 0.5, inf).amin(-1), torch.where(in_row, v - 0.5, inf).amin(-1)], -1
        )
        self.box_max = torch.stack(
            [torch.where(in_col, u + 0.5, -inf).amax(-1), torch.where(in_row, v + 0.5, -inf).amax(-1)], -1
        )
