"""Per-frame signal filters of the contract's ``contact`` key, in NumPy (used by the readers and the optimiser)."""

from __future__ import annotations

import numpy as np


def majority_filter(signal: np.ndarray, window: int = 5) -> np.ndarray:
    """Per-frame majority vote of a boolean signal over ``window`` frames (the paper's code:
    5 frames, 3 votes), which removes isolated flips. Near the ends the vote is over the
    frames that exist. A signal the vote would erase entirely is returned unchanged.
    """
    signal = np.asarray(signal, dtype=bool)
    kernel = np.ones(window, dtype=int)
    # "full" then cut (not mode="same", which returns max(N, window) values for a video shorter than the window).
    first, n = (window - 1) // 2, len(signal)
    votes = np.convolve(signal.astype(int), kernel)[first : first + n]
    frames = np.convolve(np.ones(n, dtype=int), kernel)[first : first + n]
    filtered = 2 * votes > frames
    return filtered if filtered.any() else signal
