"""The engine's launch scope on the CPU: denormals flushed inside, freed memory kept for reuse."""

import resource
import sys

import pytest
import torch

from warpskill.engine.warp_bridge import keep_freed_memory, warp_scope


def test_denormals_are_flushed_inside_the_scope_and_restored_after():
    tiny = torch.tensor(1e-40, dtype=torch.float32)
    assert tiny.item() != 0.0
    with warp_scope(torch.device("cpu")):
        assert (tiny * 1.0).item() == 0.0
    assert (tiny * 1.0).item() != 0.0


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_image_sized_buffers_are_reused_without_page_faults():
    assert keep_freed_memory()
    shape = (110, 2, 60, 107)  # a raster layer of stage (a) on a dev video: 5.6 MB
    for _ in range(3):  # warm the heap up
        torch.zeros(shape)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(20):
        torch.zeros(shape)
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
    assert faults < 20 * 1400 // 10  # fresh pages would cost 1,400 faults per buffer
