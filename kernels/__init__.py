"""Warp kernels of warpskill, installed as ``warpskill.kernels``."""
