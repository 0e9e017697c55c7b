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
