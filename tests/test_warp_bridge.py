"""The engine's launch scope on the CPU (denormals flushed inside) and its pool of buffers."""

import torch

from warpskill.engine.warp_bridge import WorkspacePool, warp_scope


def test_denormals_are_flushed_inside_the_scope_and_restored_after():
    tiny = torch.tensor(1e-40, dtype=torch.float32)
    assert tiny.item() != 0.0
    with warp_scope(torch.device("cpu")):
        assert (tiny * 1.0).item() == 0.0
    assert (tiny * 1.0).item() != 0.0


def test_a_workspace_given_back_twice_is_handed_out_once():
    pool = WorkspacePool(lambda key: object())
    first = pool.take("shape")
    pool.give_back("shape", first)
    pool.give_back("shape", first)  # a retained graph's second backward pass
    assert pool.take("shape") is first
    assert pool.take("shape") is not first
