"""The devices every kernel test runs on: each device Warp sees (``wp.get_devices()``)."""

import torch
import warp as wp


def warp_devices() -> list[str]:
    """Warp's devices: ``"cpu"``, and ``"cuda:i"`` for each GPU."""
    wp.init()
    return [str(device) for device in wp.get_devices()]


def torch_devices() -> list[str]:
    """Those of :func:`warp_devices` that Torch can also use (a CPU build of Torch has no CUDA)."""
    return [d for d in warp_devices() if d == "cpu" or (torch.cuda.is_available() and d.startswith("cuda"))]
