"""The results folder ``OUT/<name>/``: finished means it loads, atomic writes, a full disk, the lock."""

import dataclasses
import errno
import logging
import os
import subprocess
import sys
import time

import numpy as np
import pytest
from test_something_else import _messy, _write

from warpskill.cli import main
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.results_folder import ResultsFolder, ResultsFolderError
from warpskill.optimizer.options import OptimizeOptions
from warpskill.synthetic import make_demonstration

# Holds the folder's lock, says so, then writes the reconstruction read from argv[2] into it.
HOLDER = """
import sys, time
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.results_folder import ResultsFolder
keeper = ResultsFolder(sys.argv[1])
with keeper.locked():
    print("held", flush=True)
    time.sleep(1.0)
    keeper.save(Reconstruction.load(sys.argv[2]), keeper.reconstruction)
"""


@pytest.fixture(scope="module")
def truth():
    return Reconstruction(**make_demonstration("pick_up", seed=0, noise="none").truth)


def _temporary_files(folder):
    return sorted(path.name for path in folder.iterdir() if path.name.endswith(".tmp"))


def test_writes_are_atomic_and_leave_no_temporary_file(truth, tmp_path):
    keeper = ResultsFolder(tmp_path / "x")
    assert keeper.save(truth, keeper.reconstruction) == tmp_path / "x" / "reconstruction.npz"
    keeper.record_error("Traceback: it failed\n")
    np.testing.assert_array_equal(keeper.finished_reconstruction().object_pos, truth.object_pos)
    assert keeper.error.read_text() == "Traceback: it failed\n"
    assert _temporary_files(keeper.path) == []


def test_a_corrupt_result_is_reported_in_one_line_and_not_finished(tmp_path, caplog):
    keeper = ResultsFolder(tmp_path)
    keeper.reconstruction.write_bytes(b"PK\x03\x04 not really a zip archive")
    assert keeper.finished_reconstruction() is None
    assert keeper.finished_replay() is None  # missing: not finished, nothing to say
    [line] = caplog.messages
    assert line.startswith(f"{keeper.reconstruction} is corrupt (not a readable .npz archive (BadZipFile")
    assert line.endswith("): redoing it")


def test_a_reconstruction_made_with_other_options_is_not_finished(truth, tmp_path, caplog):
    asked = OptimizeOptions(device="cpu", seed=1)
    keeper = ResultsFolder(tmp_path)
    keeper.save(dataclasses.replace(truth, options=np.array(asked.to_json())), keeper.reconstruction)
    assert keeper.finished_reconstruction(asked.to_json()) is not None
    assert keeper.finished_reconstruction(dataclasses.replace(asked, device="cuda").to_json()) is not None
    assert keeper.finished_reconstruction() is not None  # no options asked: any will do
    assert caplog.messages == []
    other = asked.with_settings(["config.init_iterations=4"])
    assert keeper.finished_reconstruction(other.to_json()) is None
    assert keeper.finished_reconstruction(dataclasses.replace(asked, seed=2).to_json()) is None
    assert caplog.messages == [f"{keeper.reconstruction}: made with other options; redoing the step"] * 2
    caplog.clear()
    keeper.save(truth, keeper.reconstruction)  # records no options: made elsewhere, taken as it is
    assert keeper.finished_reconstruction(asked.to_json()) is not None
    assert caplog.messages == []


def test_a_full_disk_keeps_the_previous_result_and_says_so(truth, tmp_path, monkeypatch):
    keeper = ResultsFolder(tmp_path / "x")
    keeper.save(truth, keeper.reconstruction)
    before = keeper.reconstruction.read_bytes()

    def disk_full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "fsync", disk_full)
    later = dataclasses.replace(truth, fps=2 * truth.fps)
    with pytest.raises(ResultsFolderError) as caught:
        keeper.save(later, keeper.reconstruction)
    assert str(caught.value) == f"no space left on device writing {keeper.reconstruction}; the previous file is intact"
    with pytest.raises(ResultsFolderError, match="; nothing was written$"):
        keeper.save(later, keeper.initialisation)
    assert keeper.reconstruction.read_bytes() == before
    assert not keeper.initialisation.exists() and _temporary_files(keeper.path) == []


def test_a_second_process_waits_for_the_lock_and_the_result_is_whole(truth, tmp_path, caplog):
    caplog.set_level(logging.INFO, logger="warpskill")
    folder, source = tmp_path / "x", tmp_path / "source.npz"
    truth.save(source)
    first = subprocess.Popen([sys.executable, "-c", HOLDER, str(folder), str(source)], stdout=subprocess.PIPE, text=True)
    try:
        assert first.stdout.readline().strip() == "held"
        start = time.perf_counter()
        with ResultsFolder(folder).locked() as keeper:
            waited = time.perf_counter() - start
            written_first = keeper.finished_reconstruction()  # the first process's result, complete
            keeper.save(dataclasses.replace(truth, fps=2 * truth.fps), keeper.reconstruction)
            with keeper.locked():  # a nested block of the same process shares the lock
                pass
    finally:
        first.wait(timeout=120)
    assert first.returncode == 0
    assert caplog.messages == [f"{folder}: being written by pid {first.pid}; waiting for it to finish"]
    assert waited > 0.3 and written_first.fps == truth.fps
    assert ResultsFolder(folder).finished_reconstruction().fps == 2 * truth.fps
    assert _temporary_files(folder) == []


def test_the_attempts_log_counts_one_line_per_attempt(tmp_path):
    keeper = ResultsFolder(tmp_path)
    assert [keeper.log_attempt(), keeper.log_attempt()] == [1, 2]
    pid, stamp = keeper.attempts.read_text().splitlines()[-1].split()
    assert int(pid) == os.getpid() and abs(float(stamp) - time.time()) < 60
    keeper.clear_attempts()
    assert keeper.log_attempt() == 1


@pytest.mark.slow
def test_the_bench_redoes_a_corrupt_reconstruction(tmp_path, capsys):
    paths = _write(tmp_path, _messy())
    out = tmp_path / "out"
    argv = ["bench", "something-else", "--annotations", str(paths[0]), "--phases", str(paths[1]),
            "--actions", str(paths[2]), "-o", str(out), "--iterations", "2", "--set", "config.init_iterations=3"]
    keeper = ResultsFolder(out / "7")
    keeper.path.mkdir(parents=True)
    keeper.reconstruction.write_bytes(b"half a file")
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert text.count("is corrupt") == 1 and f"{keeper.reconstruction} is corrupt (" in text
    assert "reconstructed" in next(line for line in text.splitlines() if line.split()[:1] == ["7"])
    assert keeper.finished_reconstruction() is not None
    assert main(argv) == 0  # a rerun finds it finished
    assert "done before" in capsys.readouterr().out
