"""Shared fixtures of the test suite."""

import pytest
import warp as wp


@pytest.fixture
def verify_array_access():
    """Make Warp raise on array accesses that would corrupt a tape's gradients (restored after)."""
    wp.init()
    previous = wp.config.verify_autograd_array_access
    wp.config.verify_autograd_array_access = True
    yield
    wp.config.verify_autograd_array_access = previous
