"""Warp kernels of warpskill, installed as ``warpskill.kernels``."""

OPTIMIZATION_LEVEL = 3
"""Clang's optimisation level for these kernels on the CPU (Warp's default there is 2; 3 is
its CUDA default). No fast-math: the results are those of level 2, bit for bit."""
