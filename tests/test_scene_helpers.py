"""Small scene helpers of the optimiser: rotations, support heights, contact filtering."""

import numpy as np
import pytest
import torch

from warpskill.contract.signals import majority_filter
from warpskill.engine.distances import box_signed_distance, support_height
from warpskill.engine.rotations import (
    rotation_from_6d,
    rotation_log,
    rotation_to_6d,
    yaw_rotation,
)
from warpskill.optimizer.physical_start import START_CLEARANCE, clear_of_statics
from warpskill.optimizer.scene import positive, positive_inverse
from warpskill.optimizer.stage_a import far_from_contact


def test_6d_rotations_are_orthonormal_and_round_trip():
    x = torch.randn(10, 6, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    R = rotation_from_6d(x)
    eye = torch.eye(3, dtype=torch.float64).expand(10, 3, 3)
    torch.testing.assert_close(R @ R.transpose(-1, -2), eye)
    torch.testing.assert_close(torch.linalg.det(R), torch.ones(10, dtype=torch.float64))
    torch.testing.assert_close(rotation_from_6d(rotation_to_6d(R)), R)


def test_rotation_log_inverts_the_exponential():
    axis_angle = torch.tensor([[0.3, -0.2, 0.5], [1e-6, 0.0, 0.0], [0.0, 2.5, 0.0]], dtype=torch.float64)
    R = torch.linalg.matrix_exp(torch.cross(torch.eye(3, dtype=torch.float64)[None], axis_angle[:, None, :].expand(3, 3, 3), dim=-1).transpose(-1, -2) * -1)
    torch.testing.assert_close(rotation_log(R), axis_angle, atol=1e-6, rtol=1e-6)
    torch.testing.assert_close(yaw_rotation(torch.tensor(0.7, dtype=torch.float64)), torch.linalg.matrix_exp(
        torch.tensor([[0.0, -0.7, 0.0], [0.7, 0.0, 0.0], [0.0, 0.0, 0.0]], dtype=torch.float64)))


def test_positive_parameterisation_inverts_and_keeps_the_minimum():
    value = torch.tensor([0.011, 0.05, 0.3], dtype=torch.float64)
    torch.testing.assert_close(positive(positive_inverse(value, 0.01), 0.01), value)
    assert float(positive(torch.tensor(-50.0, dtype=torch.float64), 0.02)) >= 0.02


def test_support_is_the_static_top_over_its_footprint_else_the_ground():
    static_pos = torch.tensor([[0.0, 0.5, 0.05]])
    static_rot = yaw_rotation(torch.tensor([np.pi / 4]))
    static_size = torch.tensor([[0.2, 0.1, 0.1]])
    points = torch.tensor([[0.0, 0.5, 0.3], [0.06, 0.56, 0.3], [0.06, 0.44, 0.3], [0.5, 0.5, 0.3]])
    heights = support_height(points, static_pos, static_rot, static_size)
    # (0.06, 0.56) lies along the rotated box's long axis, (0.06, 0.44) across its short one.
    assert heights.tolist() == pytest.approx([0.1, 0.1, 0.0, 0.0])
    assert support_height(points, static_pos[:0], static_rot[:0], static_size[:0]).tolist() == [0.0] * 4


def test_box_signed_distance_inside_and_outside():
    pos, rot, size = torch.zeros(3), torch.eye(3), torch.tensor([0.2, 0.1, 0.1])
    points = torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.0, 0.08], [0.13, 0.08, 0.0]])
    d = box_signed_distance(points, pos, rot, size)
    assert d.tolist() == pytest.approx([-0.05, 0.03, float(np.hypot(0.03, 0.03))], abs=1e-5)


def _static(yaw: float = 0.0, dtype=torch.float32):
    """A 40 x 20 x 10 cm static box on the ground at the origin, yawed by ``yaw`` [rad]."""
    return (torch.tensor([[0.0, 0.0, 0.05]], dtype=dtype), yaw_rotation(torch.tensor([yaw], dtype=dtype)),
            torch.tensor([[0.4, 0.2, 0.1]], dtype=dtype))


def test_an_object_started_inside_a_static_box_is_moved_out_the_shortest_way():
    cube, eye = torch.tensor([0.05, 0.05, 0.05]), torch.eye(3)
    out = clear_of_statics(torch.tensor([0.0, 0.11, 0.025]), eye, cube, *_static())
    assert out.tolist() == pytest.approx([0.0, 0.125 + START_CLEARANCE, 0.025], abs=1e-6)  # out of the back
    on_top = clear_of_statics(torch.tensor([0.05, 0.0, 0.12]), eye, cube, *_static())
    assert on_top.tolist() == pytest.approx([0.05, 0.0, 0.125 + START_CLEARANCE], abs=1e-6)
    apart = torch.tensor([0.0, 0.13, 0.025])
    assert torch.equal(clear_of_statics(apart, eye, cube, *_static()), apart)
    # Yawed by 90 deg, the static's 40 cm side runs along y: the first cube is deep inside it,
    # and its shortest way out is up, 10 cm.
    up = clear_of_statics(torch.tensor([0.0, 0.11, 0.025]), eye, cube, *_static(np.pi / 2))
    assert up.tolist() == pytest.approx([0.0, 0.11, 0.125 + START_CLEARANCE], abs=1e-6)


def test_majority_filter_removes_isolated_flips_only():
    signal = np.array([0, 0, 1, 0, 0, 0, 1, 1, 1, 0, 1, 1, 1, 0, 0, 0], bool)
    filtered = majority_filter(signal)
    assert filtered.astype(int).tolist() == [0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0]
    ends = np.array([1, 0, 0, 0, 1, 1, 1, 0, 0, 0, 1], bool)  # flips at the first and last frame go too
    assert majority_filter(ends).astype(int).tolist() == [0, 0, 0, 0, 1, 1, 1, 0, 0, 0, 0]
    lone = np.array([0, 0, 1, 0, 0], bool)  # a single contact frame is kept rather than erased
    assert majority_filter(lone).tolist() == lone.tolist()


def test_far_from_contact_excludes_frames_next_to_contact():
    contact = torch.tensor([0, 0, 0, 0, 1, 1, 0, 0, 0, 0], dtype=torch.float32)
    assert far_from_contact(contact, 2).tolist() == [1, 1, 0, 0, 0, 0, 0, 0, 1, 1]
