"""The engine's launch scope on the CPU: denormals flushed inside."""

import torch

from warpskill.engine.warp_bridge import warp_scope


def test_denormals_are_flushed_inside_the_scope_and_restored_after():
    tiny = torch.tensor(1e-40, dtype=torch.float32)
    assert tiny.item() != 0.0
    with warp_scope(torch.device("cpu")):
        assert (tiny * 1.0).item() == 0.0
    assert (tiny * 1.0).item() != 0.0
