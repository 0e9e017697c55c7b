"""The ``warpskill bench`` commands, one module each, over the public API.

:mod:`.kernels` (Warp kernel microbenchmarks), :mod:`.speed` (an iteration of the Warp
engine against its plain-Torch reference, and ``optimize_many`` throughput),
:mod:`.synthetic` (the success table on synthetic demonstrations), :mod:`.something_else`
(the table on annotated real videos) and :mod:`.robot` (retarget and replay). May import
every other layer; nothing imports it but the command line.
"""

__all__ = ["kernels", "robot", "something_else", "speed", "synthetic", "timing"]
