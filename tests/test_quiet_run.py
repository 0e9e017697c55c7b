"""A quiet run: no CUDA driver warning on a machine without one (warpskill.warp_log), progress bars only
on a terminal (warpskill.progress)."""

from __future__ import annotations

import os
import struct
import subprocess
import sys

import pytest

from warpskill.warp_log import VERBOSE_ENV, cuda_driver_found

BAR = "from warpskill.progress import progress_bar; sum(progress_bar(range(50), desc='counting'))"


def _python(code: str, **options) -> subprocess.CompletedProcess:
    """``python -c CODE`` in a fresh process (Warp initialised from scratch), :data:`VERBOSE_ENV` unset."""
    env = {key: value for key, value in os.environ.items() if key != VERBOSE_ENV}
    return subprocess.run([sys.executable, "-c", code], env=env, timeout=120, **options)


@pytest.mark.skipif(cuda_driver_found(), reason="a CUDA driver is present: Warp prints no missing-driver warning")
def test_no_cuda_warning_without_a_driver():
    done = _python("import warpskill.engine", capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "CUDA" not in done.stdout + done.stderr


@pytest.mark.skipif(cuda_driver_found(), reason="a CUDA driver is present: this checks the CPU-only line")
def test_verbose_names_the_device_once():
    code = "from warpskill.warp_log import configure_warp_log as c; c(True); c(True)"
    done = _python(code, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "Could not find or load" not in done.stderr
    assert done.stderr.count("warpskill: Warp ") == 1 and "on cpu (no CUDA driver)" in done.stderr


def test_no_bar_off_a_terminal():
    done = _python(BAR, capture_output=True, text=True)
    assert done.returncode == 0 and done.stderr == ""


@pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals are POSIX")
def test_bar_on_a_terminal():
    fcntl, termios = pytest.importorskip("fcntl"), pytest.importorskip("termios")
    terminal, child = os.openpty()
    fcntl.ioctl(child, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))  # a new one has no width
    try:
        done = _python(BAR, stderr=child, stdout=subprocess.DEVNULL)
        os.close(child)
        drawn = os.read(terminal, 65536).decode()
    finally:
        os.close(terminal)
    assert done.returncode == 0 and "\r" in drawn and "counting" in drawn
