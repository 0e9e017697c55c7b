"""``warpskill.cluster``: many demonstrations over a local Ray of 2 workers, nothing lost."""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

ray = pytest.importorskip("ray")

# Every test here shares one local Ray cluster and optimises through it (seconds each).
pytestmark = pytest.mark.slow

from warpskill.cluster.runner import optimize_folder, ray_session
from warpskill.contract.reconstruction import FIELD_SHAPES, Reconstruction  # noqa: E402
from warpskill.optimizer.config import OptimizeConfig
from warpskill.optimizer.pipeline import optimize
from warpskill.synthetic import make_demonstration  # noqa: E402

SMALL = dict(image_size=(48, 85), duration=1.5)
CONFIG = OptimizeConfig(init_iterations=12)
ITERATIONS, SEED = 4, 3


@pytest.fixture(scope="module")
def cluster():
    """One local Ray of 2 workers for every test here (start-up takes seconds)."""
    with ray_session(workers=2):
        yield


@pytest.fixture(scope="module")
def demos(tmp_path_factory):
    folder = tmp_path_factory.mktemp("demos")
    made = {
        "pick": make_demonstration("pick_up", seed=0, **SMALL),
        "push": make_demonstration("push_left_to_right", seed=1, **SMALL),
        "onto": make_demonstration("put_onto", seed=2, **SMALL),
    }
    for name in ("pick", "onto"):  # two by file (read in their task), one passed as it is
        made[name].save(folder / f"{name}.npz")
    (folder / "corrupt.npz").write_bytes(b"PK\x03\x04 not really a zip archive")
    np.savez(folder / "invalid.npz", hand_mask=np.zeros((3, 8, 8), np.uint8))  # no object mask, no contact
    sources = {"pick": folder / "pick.npz", "push": made["push"], "onto": folder / "onto.npz",
               "corrupt": folder / "corrupt.npz", "invalid": folder / "invalid.npz"}
    return made, sources


@pytest.fixture(scope="module")
def run(cluster, demos, tmp_path_factory):
    out = tmp_path_factory.mktemp("cluster") / "out"
    summary = optimize_folder(demos[1], out, workers=2, iterations=ITERATIONS, seed=SEED, config=CONFIG,
                              progress=False)
    return out, summary


def test_each_reconstruction_equals_the_serial_one(run, demos):
    out, summary = run
    assert summary.done == ["pick", "push", "onto"]
    for name, demo in demos[0].items():
        assert summary.outcomes[name].status == "done" and summary.outcomes[name].attempts == 1
        assert 0 < summary.outcomes[name].optimize_seconds <= summary.outcomes[name].seconds
        parallel = Reconstruction.load(out / name / "reconstruction.npz")
        serial = optimize(demo, iterations=ITERATIONS, seed=SEED, config=CONFIG, progress=False)
        for key in FIELD_SHAPES:
            a, b = getattr(parallel, key), getattr(serial, key)
            if np.asarray(a).dtype.kind in "fc":
                np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-5, err_msg=f"{name}.{key}")
            else:
                assert np.array_equal(a, b), f"{name}.{key}"
        assert (out / name / "checkpoint.pt").exists()


def test_bad_demonstrations_fail_alone_with_their_reason(run):
    out, summary = run
    assert set(summary.failed) == {"corrupt", "invalid"}
    assert "not a readable .npz archive" in summary.failed["corrupt"]
    assert "missing required key" in summary.failed["invalid"]
    assert (out / "corrupt" / "error.txt").exists() and not (out / "corrupt" / "reconstruction.npz").exists()
    text = str(summary)
    assert "3 done, 2 failed" in text and "corrupt: failed (DemonstrationError" in text


def test_a_rerun_skips_the_finished_ones(run, demos, capsys):
    out, _ = run
    stamps = {name: (out / name / "reconstruction.npz").stat().st_mtime_ns for name in demos[0]}
    good = {name: source for name, source in demos[1].items() if name in stamps}
    summary = optimize_folder(good, out, workers=2, iterations=ITERATIONS, seed=SEED, config=CONFIG)
    assert {o.status for o in summary.outcomes.values()} == {"done before"}
    assert stamps == {name: (out / name / "reconstruction.npz").stat().st_mtime_ns for name in demos[0]}


def test_a_killed_worker_is_retried_from_its_checkpoint(cluster, demos, tmp_path):
    """SIGKILL the worker once its checkpoint exists: Ray retries the task, which resumes it."""
    out = tmp_path / "out"
    folder = out / "slow"
    killed = []

    def kill_when_checkpointed():
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not killed:
            pid_file = folder / "worker.pid"
            if (folder / "checkpoint.pt").exists() and pid_file.exists():
                pid = int(pid_file.read_text())
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
            time.sleep(0.01)

    killer = threading.Thread(target=kill_when_checkpointed, daemon=True)
    killer.start()
    config = OptimizeConfig(init_iterations=60, checkpoint_every=5)
    summary = optimize_folder({"slow": demos[0]["pick"], "other": demos[0]["push"]}, out, workers=2,
                              iterations=10, seed=SEED, config=config, progress=False, retries=2)
    killer.join()
    assert killed, "the task ended before its first checkpoint"
    outcome = summary.outcomes["slow"]
    assert outcome.status == "done", outcome.reason
    assert outcome.attempts == 2 and outcome.resumed
    assert summary.outcomes["other"].status == "done"
    pids = [int(line.split()[0]) for line in (folder / "attempts.log").read_text().splitlines()]
    assert pids[0] == killed[0] and pids[1] != killed[0]
    Reconstruction.load(folder / "reconstruction.npz")


def test_one_progress_bar_for_the_whole_run(cluster, demos, tmp_path, capsys):
    summary = optimize_folder({"pick": demos[0]["pick"]}, tmp_path, workers=2, iterations=2, seed=SEED,
                              config=OptimizeConfig(init_iterations=2), init_only=True)
    assert summary.done == ["pick"]
    err = capsys.readouterr().err
    assert "optimize" in err and "done=1" in err and "failed=0" in err
    assert "initialisation" not in err and "physics" not in err  # the tasks show no bars of their own
