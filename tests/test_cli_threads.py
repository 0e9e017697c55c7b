"""``warpskill --torch-threads``: Torch's CPU threads of the process (warpskill.cli.set_torch_threads)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from warpskill.cli import main


def _threads_after(*argv: str, omp: str | None = None, torch_first: bool = False) -> int:
    """Torch's CPU threads after ``warpskill ARGV`` in a fresh process (``OMP_NUM_THREADS=omp``),
    Torch imported before the command (``torch_first``) or after it."""
    env = {key: value for key, value in os.environ.items() if key != "OMP_NUM_THREADS"}
    if omp is not None:
        env["OMP_NUM_THREADS"] = omp
    run = "from warpskill.cli import main; main(sys.argv[1:])"
    code = f"import sys; {'import torch; ' if torch_first else ''}{run}; import torch; print(torch.get_num_threads())"
    done = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, env=env, timeout=120)
    return int(done.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("torch_first", [False, True])
def test_one_torch_thread_unless_asked_or_set_by_omp(tmp_path, torch_first):
    missing = str(tmp_path / "missing.npz")  # the command fails; the threads are set before it runs
    assert _threads_after("evaluate", missing, torch_first=torch_first) == 1
    assert _threads_after("--torch-threads", "2", "evaluate", missing, torch_first=torch_first) == 2
    assert _threads_after("evaluate", missing, omp="2", torch_first=torch_first) == 2


def test_torch_threads_must_be_positive(capsys):
    with pytest.raises(SystemExit):
        main(["--torch-threads", "0", "evaluate", "x.npz"])
    assert "must be >= 1, got 0" in capsys.readouterr().err
