"""The ``warpskill bench`` commands, one module each, over the public API.

:mod:`.kernels` (Warp kernel microbenchmarks), :mod:`.speed` (an iteration of the Warp
engine against its plain-Torch reference, and ``optimize_many`` throughput),
:mod:`.synthetic` (the success table on synthetic demonstrations), :mod:`.something_else`
(the table on annotated real videos), :mod:`.second_opinion` (an independent generator's
scenes through the real-video reader), :mod:`.footage` (real clips' masks against people's
boxes), :mod:`.robot` (retarget and replay); :mod:`.cases` (the one flow of a real-video
case, ``run_case``, shared by the two real-video tables), :mod:`.settings` (the data folders,
given as options or environment variables), :mod:`.outcomes` (each success benchmark's
per-case records and the flips since a baseline), and :mod:`.report` (the one place a
benchmark prints: its tables; its outcome tables written). Readers and metrics of the data
are :mod:`warpskill.data`'s. Per-case progress goes through :mod:`logging`. May import every
other layer; nothing imports it but the command line.
"""

__all__ = ["cases", "footage", "kernels", "outcomes", "report", "robot", "second_opinion", "settings", "something_else",
           "speed", "synthetic", "timing"]
