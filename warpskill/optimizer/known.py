"""Known lengths: quantities of the scene given in metres, which fix its scale.

Masks alone leave the scene's size to one cue, the fixed-size hand's apparent width; a
length known in advance (the object's height, the camera's height, a static box's size)
replaces it. Both stages hold such a quantity exactly: stage (a) by choosing its global
scale so that the quantity comes out at the known value, stage (b) by fixing that size (or
the camera height) instead of optimising it.
"""

from __future__ import annotations

from typing import Mapping

import torch

KNOWN_LENGTHS = (
    "object_height", "object_width", "object_depth", "camera_height", "static_height", "static_width", "static_depth",
)
"""Names of the lengths :func:`warpskill.optimize` accepts in ``known`` [m]: the manipulated
object's and the first static box's size along z (height), x (width) and y (depth) of
their own frames, and the camera's height above the ground."""

_AXES = {"width": 0, "depth": 1, "height": 2}


def check_known(known: Mapping[str, float] | None) -> dict[str, float]:
    """``known`` as a plain dict of positive floats, its names checked against :data:`KNOWN_LENGTHS`."""
    out = {}
    for name, value in (known or {}).items():
        if name not in KNOWN_LENGTHS:
            raise ValueError(f"unknown length {name!r}; known lengths: {', '.join(KNOWN_LENGTHS)}")
        value = float(value)
        if not value > 0:
            raise ValueError(f"known length {name} must be positive, got {value}")
        out[name] = value
    return out


def parse_known(items: list[str] | None) -> dict[str, float]:
    """``["object_height=0.10", ...]`` (the command line's ``--known``) -> a checked dict."""
    known = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"--known expects NAME=METRES, got {item!r}")
        try:
            known[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--known {item!r}: {value!r} is not a number") from None
    return check_known(known)


def measured(name: str, object_size: torch.Tensor, static_size: torch.Tensor, camera_height: torch.Tensor):
    """The quantity ``name`` of a scene (a 0-d tensor), or None when the scene has no such part."""
    if name == "camera_height":
        return camera_height
    part, _, axis = name.partition("_")
    if part == "object":
        return object_size[_AXES[axis]]
    if static_size.shape[0] == 0:
        return None
    return static_size[0, _AXES[axis]]


def pin_sizes(
    known: Mapping[str, float], object_size: torch.Tensor, static_size: torch.Tensor, camera_height: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Object size (3,), static sizes (K, 3) and camera height with the known lengths put in exactly."""
    for name, value in known.items():
        part, _, axis = name.partition("_")
        if name == "camera_height":
            camera_height = torch.full_like(camera_height, value)
        elif part == "object":
            mask = torch.zeros(3, dtype=torch.bool, device=object_size.device)
            mask[_AXES[axis]] = True
            object_size = torch.where(mask, torch.full_like(object_size, value), object_size)
        elif static_size.shape[0]:
            mask = torch.zeros_like(static_size, dtype=torch.bool)
            mask[0, _AXES[axis]] = True
            static_size = torch.where(mask, torch.full_like(static_size, value), static_size)
    return object_size, static_size, camera_height
