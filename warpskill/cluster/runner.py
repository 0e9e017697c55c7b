"""``optimize_folder``: many demonstrations over Ray tasks, each into its own ``OUT/<name>/``.

On the CPU, Warp runs a kernel on one thread and batching does not pay (the work grows
linearly with the batch), so each task is one demonstration on one core, and as many
tasks run at a time as there are workers: a queue that keeps every core busy. On GPUs each
task is one :func:`~warpskill.optimizer.optimize_many` batch on one GPU (``num_gpus=1``),
the demonstrations split evenly over the GPUs.

Nothing is lost: a task writes ``OUT/<name>/reconstruction.npz`` atomically and keeps its
checkpoint in ``OUT/<name>/checkpoint.pt`` as it goes; a rerun skips the demonstrations
whose reconstruction is there and was made with the same options (the device aside); a
worker that dies (killed, out of memory) is retried by Ray (``max_retries``) and the retry
resumes the checkpoint; a demonstration that cannot be read or optimised fails alone, its
reason in the :class:`Summary` and ``OUT/<name>/error.txt``.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.util
import logging
import math
import os
import shutil
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator, Mapping, Union

from tqdm.auto import tqdm

from warpskill.contract.demonstration import Demonstration
from warpskill.contract.reconstruction import Reconstruction
from warpskill.contract.results_folder import ResultsFolder
from warpskill.optimizer.options import OptimizeOptions
from warpskill.optimizer.pipeline import optimize_many
from warpskill.progress import on_terminal

INSTALL_HINT = 'pip install -e ".[cluster]"'
PID = "worker.pid"  #: the pid of the worker process running the demonstration (removed when it ends)
BATCHES = ".checkpoints"  #: OUT/.checkpoints/<group>.pt: the checkpoints of multi-demonstration (GPU) batches

Source = Union[str, os.PathLike, Demonstration]
Postprocess = Callable[[Reconstruction, Demonstration, Path], object]


@dataclass
class Outcome:
    """What became of one demonstration."""

    name: str
    status: str  #: "done" (optimised now), "done before" (its reconstruction was there) or "failed"
    folder: Path
    reason: str = ""  #: why it failed (or what went wrong after the reconstruction was written)
    seconds: float = 0.0  #: time in its task (a batch's time for each of its demonstrations)
    cpu_seconds: float = 0.0  #: CPU time of its task's process (all threads) in that time
    optimize_seconds: float = 0.0  #: time of its reconstruction alone (both stages; a batch's for each)
    attempts: int = 0  #: tasks that started on it in this run (more than 1: a worker died and Ray retried)
    resumed: bool = False  #: the last attempt started from a checkpoint

    @property
    def ok(self) -> bool:
        return self.status != "failed"

    @property
    def reconstruction(self) -> Path:
        return ResultsFolder(self.folder).reconstruction


@dataclass
class Summary:
    """The outcome of every demonstration of an :func:`optimize_folder` run, and its times."""

    outcomes: dict[str, Outcome]
    workers: int  #: tasks that ran at a time
    wall_seconds: float  #: the whole call, Ray's start-up included
    startup_seconds: float = 0.0  #: starting (or joining) Ray
    address: str | None = None  #: the cluster joined; None for the local Ray of the call
    extra: dict = field(default_factory=dict)

    @property
    def done(self) -> list[str]:
        return [name for name, outcome in self.outcomes.items() if outcome.ok]

    @property
    def failed(self) -> dict[str, str]:
        return {name: outcome.reason for name, outcome in self.outcomes.items() if not outcome.ok}

    def __str__(self) -> str:
        lines = []
        for name, o in self.outcomes.items():
            detail = f"{o.seconds:.1f} s, {o.cpu_seconds:.1f} s CPU" if o.status == "done" else ""
            if o.attempts > 1:
                detail += f", {o.attempts} attempts" + (" (resumed its checkpoint)" if o.resumed else "")
            if o.reason:
                detail += (", " if detail else "") + o.reason
            lines.append(f"  {name}: {o.status}" + (f" ({detail})" if detail else ""))
        where = self.address or "local Ray"
        lines.append(f"{len(self.done)} done, {len(self.failed)} failed in {self.wall_seconds:.1f} s "
                     f"({self.workers} worker(s), {where}, start-up {self.startup_seconds:.1f} s)")
        return "\n".join(lines)


def ray_available() -> bool:
    """Whether Ray is installed (the ``cluster`` extra)."""
    return importlib.util.find_spec("ray") is not None


@contextlib.contextmanager
def ray_session(workers: int | None = None, address: str | None = None, *, gpus: int | None = None) -> Iterator[str | None]:
    """Ray for the duration of the block; yields the address joined (None: a local Ray).

    An already initialised Ray (``ray.init`` by the caller) is used as it is and left running.
    With ``address`` (or ``RAY_ADDRESS``), joins that cluster. Otherwise starts a local Ray
    for the block, quietly: ``workers`` CPUs (default: every core), ``gpus`` GPUs (default:
    Ray's count), no dashboard, logs in a temporary folder removed afterwards.

    Raises:
        ModuleNotFoundError: Ray is not installed (the message says how to install it).
    """
    try:
        import ray  # optional extra: cluster
    except ModuleNotFoundError as error:
        raise ModuleNotFoundError(f"Ray is not installed: {INSTALL_HINT}", name="ray") from error
    if ray.is_initialized():
        yield address
        return
    address = address or os.environ.get("RAY_ADDRESS") or None
    quiet = dict(log_to_driver=False, logging_level=logging.ERROR)
    if address:
        ray.init(address=address, **quiet)
        try:
            yield address
        finally:
            ray.shutdown()
        return
    temp = tempfile.mkdtemp(prefix="warpskill-ray-")
    try:
        ray.init(num_cpus=workers or os.cpu_count() or 1, num_gpus=gpus, include_dashboard=False,
                 object_store_memory=512 * 2**20, _temp_dir=temp, **quiet)
        try:
            yield None
        finally:
            ray.shutdown()
    finally:
        shutil.rmtree(temp, ignore_errors=True)


def optimize_folder(
    demos: Mapping[str, Source],
    out: str | os.PathLike,
    options: OptimizeOptions | None = None,
    *,
    workers: int | None = None,
    address: str | None = None,
    progress: bool = True,
    batch: int | None = None,
    retries: int = 3,
    postprocess: Postprocess | None = None,
    **fields,
) -> Summary:
    """Reconstruct many demonstrations over Ray: each into ``OUT/<name>/reconstruction.npz``.

    Each reconstruction is the one :func:`warpskill.optimize` gives for the same
    demonstration and options (up to floating-point rounding): ``options`` reaches every
    task as it is (pickled) and is saved in each reconstruction (docs/formats.md).

    Args:
        demos: name (the folder under ``out``) to a demonstration ``.npz`` path (read in its
            task: an unreadable file fails alone) or a :class:`Demonstration`.
        out: output folder.
        workers: tasks at a time: CPU cores (default: every core of the local Ray, or the
            cluster's CPUs), or GPUs with a ``cuda`` device (default: every GPU).
        address: a Ray cluster to join (default ``RAY_ADDRESS``; none: a local Ray of
            ``workers`` CPUs for the call). Its nodes need warpskill installed and ``out``
            shared.
        options, fields: as :func:`warpskill.optimize` (:class:`OptimizeOptions`; its device
            decides CPU or GPU tasks).
        progress: one progress bar for the whole run (the tasks show none).
        batch: demonstrations per task (one ``optimize_many`` call); default 1 on the CPU,
            the demonstrations split evenly over the workers on GPUs.
        retries: Ray's retries of a task whose worker died.
        postprocess: ``f(reconstruction, demonstration, folder)``, run in the task after the
            reconstruction is written (pictures, ...); a picklable module-level function.

    Returns:
        The :class:`Summary` (per demonstration: done, done before, or failed and why).

    Raises:
        ModuleNotFoundError: Ray is not installed.
        ValueError: a name is not a plain folder name.
    """
    start = time.perf_counter()
    out = Path(out)
    options = OptimizeOptions.build(options, **fields)
    device = options.device
    if not (device is None or device == "cpu" or str(device).startswith("cuda")):
        raise ValueError(f"device {device!r}: warpskill runs on 'cpu' or 'cuda'")
    outcomes, pending = _done_before(demos, out, options)
    gpu = str(device or "cpu").startswith("cuda")
    if not pending:
        return Summary(outcomes, workers or 0, time.perf_counter() - start)
    for _, _, folder in pending:  # this run's attempts only
        (folder / PID).unlink(missing_ok=True)
        ResultsFolder(folder).clear_attempts()
    pending.sort(key=lambda item: -_size(item[1]))  # longest first: the last task to start is a short one
    import ray  # optional extra: cluster

    with ray_session(None if gpu else workers, address, gpus=workers if gpu and not address else None) as joined:
        startup = time.perf_counter() - start
        resources = ray.cluster_resources()
        if gpu and resources.get("GPU", 0) < 1:
            raise ValueError(f"device {device!r}: the Ray cluster has no GPU")
        slots = workers or max(1, int(resources.get("GPU" if gpu else "CPU", 1)))
        size = batch or (math.ceil(len(pending) / slots) if gpu else 1)
        groups = [pending[i::math.ceil(len(pending) / size)] for i in range(math.ceil(len(pending) / size))]
        task = _remote().options(num_cpus=1, num_gpus=1 if gpu else 0, max_retries=retries)
        outcomes.update(_run(ray, task, groups, options, postprocess, out, slots, len(demos), len(outcomes), progress))
    ordered = {name: outcomes[name] for name in demos}
    return Summary(ordered, slots, time.perf_counter() - start, startup, joined)


def _done_before(demos: Mapping[str, Source], out: Path,
                 options: OptimizeOptions) -> tuple[dict[str, Outcome], list[tuple[str, Source, Path]]]:
    """The demonstrations whose folder under ``out`` holds a finished reconstruction with ``options``
    (their outcomes), and the others as (name, source, folder), in ``demos``' order.

    Raises:
        ValueError: a name is not a plain folder name.
    """
    for name in demos:
        if not name or name.startswith(".") or os.sep in name or (os.altsep and os.altsep in name):
            raise ValueError(f"demonstration name {name!r} is not a plain folder name")
    outcomes: dict[str, Outcome] = {}
    pending: list[tuple[str, Source, Path]] = []
    for name, source in demos.items():
        folder = out / name
        if ResultsFolder(folder).finished_reconstruction(options.to_json()) is not None:
            outcomes[name] = Outcome(name, "done before", folder)
        else:
            pending.append((name, source, folder))
    return outcomes, pending


def _run(ray, task, groups, options: OptimizeOptions, postprocess: Postprocess | None, out: Path, slots: int,
         total: int, before: int, progress: bool) -> dict[str, Outcome]:
    """Submit the groups, ``slots`` at a time; collect their outcomes under one progress bar."""
    outcomes: dict[str, Outcome] = {}
    queue, running = list(groups), {}
    bar = tqdm(total=total, initial=before, unit="demo", desc="optimize", disable=not progress, dynamic_ncols=True)
    done = before

    shown: list = []
    ticking = progress and on_terminal()  # a terminal: the clock goes on; a log: one line per change

    def show() -> None:
        counts = dict(done=done, failed=sum(not o.ok for o in outcomes.values()),
                      running=sum(len(g) for g in running.values()))
        if counts != (shown[-1] if shown else None):
            shown.append(counts)
            bar.set_postfix(counts, refresh=True)
        elif ticking:
            bar.refresh()

    try:
        show()
        while queue or running:
            while queue and len(running) < slots:
                group = queue.pop(0)
                checkpoint = out / BATCHES / f"{_digest([name for name, _, _ in group])}.pt" if len(group) > 1 else None
                items = [(name, source if isinstance(source, Demonstration) else str(source), str(folder))
                         for name, source, folder in group]
                running[task.remote(items, options, checkpoint, postprocess)] = group
            ready, _ = ray.wait(list(running), num_returns=1, timeout=1.0)
            for ref in ready:
                group = running.pop(ref)
                try:
                    results = ray.get(ref)
                except Exception as error:  # the task itself failed: its worker died every retry, ...
                    reason = f"{type(error).__name__}: {str(error).strip().splitlines()[-1] if str(error).strip() else ''}"
                    results = [dict(name=name, status="failed", reason=reason) for name, _, _ in group]
                folders = {name: Path(folder) for name, _, folder in group}
                for result in results:
                    name = result.pop("name")
                    outcomes[name] = Outcome(name, folder=folders[name], **result)
                    if outcomes[name].ok:
                        done += 1
                    bar.update(1)
            show()
    finally:
        bar.close()
        for ref in running:  # interrupted: stop what still runs (its checkpoint keeps its progress)
            ray.cancel(ref, force=True)
    return outcomes


@functools.lru_cache(maxsize=None)
def _remote():
    import ray  # optional extra: cluster

    return ray.remote(_optimize_group_locked)


def _optimize_group_locked(items: list[tuple[str, object, str]], options: OptimizeOptions, checkpoint: Path | None,
                           postprocess: Postprocess | None) -> list[dict]:
    """The Ray task: :func:`_optimize_group` holding the lock of each demonstration's folder."""
    with contextlib.ExitStack() as stack:
        for folder in sorted({folder for _, _, folder in items}):
            stack.enter_context(ResultsFolder(folder).locked())
        return _optimize_group(items, options, checkpoint, postprocess)


def _optimize_group(items: list[tuple[str, object, str]], options: OptimizeOptions, checkpoint: Path | None,
                    postprocess: Postprocess | None) -> list[dict]:
    """The Ray task: optimise one group of demonstrations with ``options`` (``checkpoint``: the
    group's, for more than one); one result dict per demonstration."""
    start, cpu = time.perf_counter(), time.process_time()
    pid = os.getpid()
    states, demos, results = {}, {}, {}
    for name, source, folder in items:
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        (folder / PID).write_text(f"{pid}\n")
        attempts = ResultsFolder(folder).log_attempt()
        resumed = ResultsFolder(folder).checkpoint.exists() or (checkpoint is not None and checkpoint.exists())
        states[name] = dict(folder=folder, attempts=attempts, resumed=resumed)
        try:
            demos[name] = source if isinstance(source, Demonstration) else Demonstration.load(source)
        except Exception as error:
            results[name] = _failure(folder, error)
    good = [name for name, _, _ in items if name in demos]
    if len(good) > 1:
        try:
            results.update(_optimize(good, demos, states, options, checkpoint, postprocess))
            good = []
        except Exception:  # one demonstration spoiled the batch: each alone below, so it fails alone
            pass
    for name in good:
        try:
            results.update(_optimize([name], demos, states, options, ResultsFolder(states[name]["folder"]).checkpoint,
                                     postprocess))
        except Exception as error:
            results[name] = _failure(states[name]["folder"], error)
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    for state in states.values():
        (state["folder"] / PID).unlink(missing_ok=True)
    return [dict(name=name, seconds=seconds, cpu_seconds=cpu, attempts=states[name]["attempts"], resumed=states[name]["resumed"],
                 **results[name]) for name, _, _ in items]


def _optimize(names, demos, states, options: OptimizeOptions, checkpoint: Path | None,
              postprocess: Postprocess | None) -> dict[str, dict]:
    start = time.perf_counter()
    reconstructions = optimize_many([demos[name] for name in names], options, progress=False, checkpoint=checkpoint)
    seconds = time.perf_counter() - start
    results = {}
    for name, recon in zip(names, reconstructions):
        folder = states[name]["folder"]
        keeper = ResultsFolder(folder)
        keeper.save(recon, keeper.reconstruction)
        keeper.clear_error()
        results[name] = dict(status="done", reason="", optimize_seconds=seconds)
        if postprocess is not None:
            try:
                postprocess(recon, demos[name], folder)
            except Exception as error:
                results[name]["reason"] = f"after the reconstruction: {type(error).__name__}: {error}"
    return results


def _failure(folder: Path, error: Exception) -> dict:
    ResultsFolder(folder).record_error(traceback.format_exc())
    return dict(status="failed", reason=f"{type(error).__name__}: {error}")


def _size(source: Source) -> float:
    """A proxy of a demonstration's optimisation time, to start the longest first."""
    if isinstance(source, Demonstration):
        return float(source.hand_mask.size)
    try:
        return float(os.path.getsize(source))
    except OSError:
        return 0.0


def _digest(names: list[str]) -> str:
    return hashlib.sha256("\0".join(sorted(names)).encode()).hexdigest()[:16]
