"""Timing helper of the benchmarks: first call (compilation) apart from the steady-state median."""

from __future__ import annotations

import statistics
import time
from typing import Callable

import torch


def timed(fn: Callable[[], object], repeats: int, device: torch.device) -> tuple[float, float]:
    """(first-call seconds, median seconds of ``repeats`` further calls) of ``fn``; the first call
    pays for compilation and caches, the median is the steady state (CUDA synchronised)."""

    def once() -> float:
        start = time.perf_counter()
        fn()
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        return time.perf_counter() - start

    first = once()
    return first, statistics.median(once() for _ in range(repeats))
