"""The demonstration as both stages fit it: masks at the working resolution, their moments, the filtered contact."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.signals import majority_filter
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.losses import MaskTargets


@dataclass
class WorkingInputs:
    """What both stages fit, at the working resolution.

    Attributes:
        intrinsics: the camera at the working resolution.
        masks: (N, 2 + K, h, w) area-averaged masks: hand, object, statics.
        targets: ``masks`` with their moments, for the dIoU.
        contact_signal: (N,) bool, the majority-filtered contact.
        contact: (N,) the same as floats on the device.
        object_visible: (N,) 1 where the object's mask is not empty.
    """

    intrinsics: object
    masks: torch.Tensor
    targets: MaskTargets
    contact_signal: np.ndarray
    contact: torch.Tensor
    object_visible: torch.Tensor


def working_inputs(demo: Demonstration, config: OptimizeConfig, device: torch.device) -> WorkingInputs:
    """The demonstration's masks and contact as the optimiser uses them (see :class:`WorkingInputs`)."""
    h, w = demo.intrinsics.scaled(config.image_scale).image_size
    masks = torch.as_tensor(demo.mask_stack(h, w), device=device)
    contact_signal = majority_filter(demo.contact)
    return WorkingInputs(
        intrinsics=demo.intrinsics.resized(h, w),
        masks=masks,
        targets=MaskTargets(masks),
        contact_signal=contact_signal,
        contact=torch.as_tensor(contact_signal, dtype=torch.float32, device=device),
        object_visible=(masks[:, 1].flatten(1).amax(1) > 0.5).float(),
    )


def _boxes(masks: np.ndarray) -> np.ndarray:
    """(N, 4) pixel bounds (col0, row0, col1, row1) of each mask (N, h, w) bool; NaN when empty."""
    out = np.full((len(masks), 4), np.nan)
    for k, mask in enumerate(masks):
        rows, cols = np.nonzero(mask)
        if len(rows):
            out[k] = cols.min(), rows.min(), cols.max(), rows.max()
    return out


def held_after_contact(masks: np.ndarray, contact: np.ndarray, *, min_frames: int = 2) -> np.ndarray:
    """(N,) bool: frames after the contact signal's end in which the object may still be held.

    Annotators may end the action phase while the hand still holds the object: it is then
    seen in the air with the hand on it, or it leaves the view with the hand. These are
    the frames from the last contact frame to the video's end when, in every one of them,
    the object's box (the bounds of its mask) touches the hand's, or the object has left
    the view: its mask is empty after it last touched the image border in contact with the
    hand. Whether it is really held there is for the physics to decide (see
    :func:`warpskill.optimize`); elsewhere, and when the run does not reach the video's
    end (the hand let go and left), nothing is returned.

    Args:
        masks: (N, 2 + K, h, w) masks in [0, 1]: hand, object, statics.
        contact: (N,) bool.
        min_frames: fewer such frames than this are ignored.
    """
    N = len(contact)
    out = np.zeros(N, dtype=bool)
    on = np.flatnonzero(contact)
    if len(on) == 0 or on[-1] > N - 1 - min_frames:
        return out
    h, w = masks.shape[-2:]
    hand, obj = _boxes(masks[:, 0] > 0.5), _boxes(masks[:, 1] > 0.5)
    visible = ~np.isnan(obj[:, 0])
    with np.errstate(invalid="ignore"):
        attached = ((hand[:, 0] <= obj[:, 2] + 1) & (obj[:, 0] <= hand[:, 2] + 1)
                    & (hand[:, 1] <= obj[:, 3] + 1) & (obj[:, 1] <= hand[:, 3] + 1))
        at_border = visible & ((obj[:, 0] <= 0) | (obj[:, 1] <= 0) | (obj[:, 2] >= w - 1) | (obj[:, 3] >= h - 1))
    end = on[-1]
    seen = np.flatnonzero(visible[: end + 1])
    gone = False
    if not visible[end]:  # the object left the view before the signal ended
        if len(seen) == 0 or not at_border[seen[-1]]:
            return out
        gone = True
    for k in range(end + 1, N):
        if visible[k]:
            if not attached[k]:
                return out
            gone = False
        elif not gone:
            if not (at_border[k - 1] and (attached[k - 1] or contact[k - 1])):
                return out
            gone = True
    out[end + 1 :] = True
    return out
