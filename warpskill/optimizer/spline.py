"""Natural cubic spline of the hand's control velocities.

The hand's velocities (v_h, w_h, grasp rate) are a natural cubic spline through control
values at uniformly spaced knots. Evaluating the spline is linear in the knot values, so it
is a fixed basis matrix applied in Torch.
"""

from __future__ import annotations

import numpy as np
import torch


def natural_cubic_basis(num_knots: int, duration: float, times: np.ndarray) -> np.ndarray:
    """Basis of the natural cubic spline with ``num_knots`` knots uniform on [0, ``duration``].

    Args:
        num_knots: number of knots (>= 2; two knots give a straight line).
        duration: time of the last knot [s] (> 0).
        times: (T,) evaluation times [s] in [0, duration].

    Returns:
        (T, num_knots) float64 matrix B: the spline through knot values y is ``B @ y``.
    """
    if num_knots < 2:
        raise ValueError(f"num_knots must be >= 2, got {num_knots}")
    if not duration > 0:
        raise ValueError(f"duration must be positive, got {duration}")
    times = np.asarray(times, dtype=np.float64)
    if times.ndim != 1:
        raise ValueError(f"times must be 1-D, got shape {times.shape}")
    tol = 1e-9 * duration
    if times.size and (times.min() < -tol or times.max() > duration + tol):
        raise ValueError(f"times must lie in [0, {duration}], got [{times.min()}, {times.max()}]")

    h = duration / (num_knots - 1)
    # Second derivatives M (zero at both ends) solve, for the interior knots i,
    # M[i-1] + 4 M[i] + M[i+1] = 6 / h^2 (y[i-1] - 2 y[i] + y[i+1]).
    second = np.zeros((num_knots, num_knots))
    if num_knots > 2:
        inner = num_knots - 2
        lhs = 4.0 * np.eye(inner) + np.eye(inner, k=1) + np.eye(inner, k=-1)
        diff = np.zeros((inner, num_knots))
        rows = np.arange(inner)
        diff[rows, rows] = diff[rows, rows + 2] = 6.0 / h**2
        diff[rows, rows + 1] = -12.0 / h**2
        second[1:-1] = np.linalg.solve(lhs, diff)

    u = np.clip(times, 0.0, duration) / h
    left = np.minimum(np.floor(u).astype(int), num_knots - 2)
    u = u - left
    rows = np.arange(times.size)
    basis = np.zeros((times.size, num_knots))
    basis[rows, left] += 1.0 - u
    basis[rows, left + 1] += u
    curve_left = h**2 / 6.0 * ((1.0 - u) ** 3 - (1.0 - u))
    curve_right = h**2 / 6.0 * (u**3 - u)
    return basis + curve_left[:, None] * second[left] + curve_right[:, None] * second[left + 1]


def step_velocities(ctrl: torch.Tensor, num_frames: int, fps: float, steps_per_frame: int) -> torch.Tensor:
    """Hand velocities at the start of every integration step.

    Args:
        ctrl: (B, num_knots, 7) knot values: v_h [m/s] (3), w_h [rad/s] (3), grasp rate
            [1/s] (1), knots uniform over the demonstration's duration (num_frames - 1) / fps.
        num_frames: number of frames N (>= 2).
        fps: frame rate [1/s].
        steps_per_frame: integration steps per frame.

    Returns:
        (B, S, 7) tensor with S = (N - 1) * steps_per_frame, step n evaluated at
        t = n / (fps * steps_per_frame); same dtype and device as ``ctrl``.
    """
    if ctrl.ndim != 3 or ctrl.shape[-1] != 7:
        raise ValueError(f"ctrl must have shape (B, num_knots, 7), got {tuple(ctrl.shape)}")
    if num_frames < 2:
        raise ValueError(f"num_frames must be >= 2, got {num_frames}")
    num_steps = (num_frames - 1) * steps_per_frame
    times = np.arange(num_steps) / (fps * steps_per_frame)
    basis = natural_cubic_basis(ctrl.shape[1], (num_frames - 1) / fps, times)
    return torch.einsum("sk,bkc->bsc", torch.as_tensor(basis, dtype=ctrl.dtype, device=ctrl.device), ctrl)
