"""The torch/Warp device a computation runs on, checked once with a clear error."""

from __future__ import annotations

import torch


def resolve_device(device: str | torch.device | None) -> torch.device:
    """The torch device named by ``device`` (default CPU).

    Raises:
        ValueError: an unknown device, or CUDA when this torch or machine has none.
    """
    try:
        resolved = torch.device(device or "cpu")
    except RuntimeError:
        raise ValueError(f"unknown device {device!r}: use 'cpu' or 'cuda'") from None
    if resolved.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"device {device!r}: CUDA is not available to this torch build or machine")
    if resolved.type not in ("cpu", "cuda"):
        raise ValueError(f"device {device!r}: warpskill runs on 'cpu' or 'cuda'")
    return resolved
