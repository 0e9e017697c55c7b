"""The colours of the pictures: hand, object and static objects (RGB, 0-255)."""

from __future__ import annotations

import numpy as np
from matplotlib.colors import to_rgb

HAND_COLOR = (255, 140, 20)


OBJECT_COLOR = (40, 200, 70)


STATIC_COLOR = (40, 110, 255)


def rgb(color: tuple[int, int, int]) -> tuple[float, float, float]:
    """An 8-bit RGB triple as matplotlib floats in [0, 1]."""
    return to_rgb(np.array(color) / 255.0)
