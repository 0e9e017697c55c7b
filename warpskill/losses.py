"""Mask losses: the distance-IoU (dIoU) of the paper, for soft rendered silhouettes."""

from __future__ import annotations

import torch

_EMPTY_MASS = 1e-3  # [px]: a mask with less total mass than this counts as empty


def diou_loss(rendered: torch.Tensor, target: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Distance-IoU loss between soft rendered masks and target masks, per mask.

    ``dIoU = 1 - IoU + |c_r - c_t|^2 / diag^2`` where ``c_r``, ``c_t`` are the mask
    centroids [px] and ``diag`` the diagonal of the smallest box enclosing both masks
    (the rendered mask's box taken where it exceeds 0.5; the box carries no gradient).

    Empty masks, as the paper treats them: where the *target* is empty (the object is
    occluded or out of view) the frame carries no perceptual term, and is reported as
    invalid; where only the *rendering* is empty the loss is its maximum, 2.

    Args:
        rendered: (..., H, W) soft masks in [0, 1].
        target: (..., H, W) masks in [0, 1] (area-averaged to the working resolution).

    Returns:
        ``(loss, valid)``: (...) dIoU per mask (0 where invalid) and the (...) bool mask
        of entries whose target is not empty.
    """
    if rendered.shape != target.shape:
        raise ValueError(f"rendered {tuple(rendered.shape)} and target {tuple(target.shape)} masks differ in shape")
    H, W = rendered.shape[-2:]
    target = target.to(rendered)
    rows = torch.arange(H, dtype=rendered.dtype, device=rendered.device) + 0.5
    cols = torch.arange(W, dtype=rendered.dtype, device=rendered.device) + 0.5

    mass_r = rendered.sum((-2, -1))
    mass_t = target.sum((-2, -1))
    intersection = (rendered * target).sum((-2, -1))
    union = mass_r + mass_t - intersection
    iou = intersection / union.clamp_min(_EMPTY_MASS)

    def centroid(mask, mass):
        u = (mask.sum(-2) * cols).sum(-1) / mass.clamp_min(_EMPTY_MASS)
        v = (mask.sum(-1) * rows).sum(-1) / mass.clamp_min(_EMPTY_MASS)
        return u, v

    ur, vr = centroid(rendered, mass_r)
    ut, vt = centroid(target, mass_t)
    lo_r, hi_r = _bounds(rendered.detach() > 0.5, cols, rows)
    lo_t, hi_t = _bounds(target > 0.5, cols, rows)
    lo = torch.minimum(lo_r, lo_t)
    hi = torch.maximum(hi_r, hi_t)
    diag2 = ((hi - lo) ** 2).sum(-1).clamp_min(1.0)
    distance = ((ur - ut) ** 2 + (vr - vt) ** 2) / diag2

    valid = mass_t > _EMPTY_MASS
    rendered_empty = mass_r <= _EMPTY_MASS
    loss = torch.where(rendered_empty, torch.full_like(iou, 2.0), 1.0 - iou + distance.clamp_max(1.0))
    return torch.where(valid, loss, torch.zeros_like(loss)), valid


def _bounds(mask: torch.Tensor, cols: torch.Tensor, rows: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Pixel-edge bounds (u_min, v_min), (u_max, v_max) of boolean masks (..., H, W).

    An empty mask gets an inverted box (+inf, -inf) so it never widens the union box.
    """
    inf = torch.tensor(float("inf"), dtype=cols.dtype, device=cols.device)
    any_col = mask.any(-2)
    any_row = mask.any(-1)
    u_min = torch.where(any_col, cols - 0.5, inf).amin(-1)
    u_max = torch.where(any_col, cols + 0.5, -inf).amax(-1)
    v_min = torch.where(any_row, rows - 0.5, inf).amin(-1)
    v_max = torch.where(any_row, rows + 0.5, -inf).amax(-1)
    return torch.stack([u_min, v_min], -1), torch.stack([u_max, v_max], -1)
