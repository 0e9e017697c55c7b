"""Warp's module-load messages: hidden by default, shown by ``warpskill --verbose`` (warpskill.warp_log)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from warpskill.contract.reconstruction import Reconstruction
from warpskill.synthetic import make_demonstration
from warpskill.warp_log import VERBOSE_ENV

pytest.importorskip("rerun")  # `warpskill view` renders the silhouettes: a cheap command that loads Warp modules


def _warpskill(*argv: str) -> str:
    """stdout and stderr of ``warpskill ARGV`` in a fresh process (Warp configured from scratch)."""
    env = {key: value for key, value in os.environ.items() if key != VERBOSE_ENV}
    code = "import sys; from warpskill.cli import main; sys.exit(main(sys.argv[1:]))"
    done = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout + done.stderr


@pytest.mark.slow
def test_warp_is_quiet_unless_verbose(tmp_path):
    demo = make_demonstration("pick_up", seed=0, noise="none", image_size=(30, 40), fps=4.0, duration=1.0)
    Reconstruction(**demo.truth).save(tmp_path / "reconstruction.npz")
    assert "load on device" not in _warpskill("view", str(tmp_path))
    assert "load on device" in _warpskill("--verbose", "view", str(tmp_path))
