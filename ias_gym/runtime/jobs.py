"""Running one picklable job per item (a seed, or a ``(class, seed)`` pair) on one of three
backends: in this process, on a pool of local worker processes, or on a Ray cluster.

:func:`iter_jobs` maps a job over items and yields the results in the items' order (as soon
as the results before them are in), :func:`run_jobs` collects them in a list. A job is a
picklable callable ``item -> result``; what it runs on is fixed by the item alone (the seed
of an episode), never by which worker ran it, so every backend gives the serial run's
results bit for bit. The evaluation, the disturbance suite and skill recording define their
jobs beside their serial code (:class:`ias_gym.evaluation.EpisodeJob`, ...).

Workers build what a job needs (an env, a policy) from the job's spec, through
:func:`worker_resource`, which keeps the last built resource per process: a worker builds
the env once and runs many seeds in it. Nothing of the parent's simulators is sent to a
worker; results come back by pickle between our own processes only.

- ``serial``: the jobs run here, one after another (resources released at the end).
- ``processes``: :class:`concurrent.futures.ProcessPoolExecutor` with the ``spawn`` start
  method (MuJoCo's OpenGL contexts and torch's thread pools do not survive ``fork``); each
  worker runs with one BLAS/OpenMP/torch thread, so ``N`` workers use ``N`` cores.
- ``ray``: Ray tasks (the ``[distributed]`` extra), on a cluster at an address or on a
  local one started here (``ray.init(num_cpus=..., include_dashboard=False)``) and shut
  down at the end; an already initialised Ray is used as it is.

Faults: a worker that dies (killed, out of memory, a crash in C) takes its job with it.
The process pool then breaks (``BrokenProcessPool``) and every job in flight with it; the
jobs that had started on a worker are retried once, each alone in a fresh one-worker pool
(so a job that kills its worker again is identified exactly and the jobs that only shared
the pool with it are not blamed), the jobs that had not started are resubmitted. Ray
retries a task whose worker died once itself (``max_retries``). A job that fails again is
reported by :class:`WorkerError` naming its items, after every other result is in: a
result is never silently missing. An exception raised *by* a job (a bad env kwarg) is not
a fault: it is raised at once, as in a serial run.

Why not joblib or ``multiprocessing.Pool``: neither tells which job's worker died (joblib's
loky reports a ``TerminatedWorkerError`` for the whole batch), and an exact retry of the one
job is what keeps a long sweep from losing all of it to one bad seed.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
from collections.abc import Callable, Hashable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from tqdm import tqdm

from ias_gym.errors import IasGymError, InputError, RayMissingError, WorkerError  # noqa: F401 - defined there, raised here

T = TypeVar("T")
R = TypeVar("R")

#: Start method of the worker processes: MuJoCo (its GL context) and torch (its thread
#: pools) are not safe in a forked child.
START_METHOD = "spawn"
#: How often a job whose worker died is retried before it is reported.
RETRIES = 1
#: The error line of ``--ray`` without Ray installed (the CLI prefixes ``ias-gym: error:``).
RAY_MISSING = "--ray needs the distributed extra: pip install 'ias-gym[distributed]'"
#: Environment variables that size the native thread pools of numpy's BLAS, OpenMP and
#: torch: one thread per worker, set before a worker imports them.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


@dataclass(frozen=True)
class Backend:
    """Where jobs run.

    Attributes:
        kind: ``"serial"`` (this process), ``"processes"`` (local worker processes) or
            ``"ray"``.
        workers: number of worker processes (``processes``; for a local Ray, its CPUs;
            ``0``: all cores).
        address: a Ray cluster's address (``"auto"``, ``"HOST:PORT"``, ``"ray://HOST:PORT"``);
            ``None``: start a local Ray.
    """

    kind: str = "serial"
    workers: int = 1
    address: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in ("serial", "processes", "ray"):
            raise InputError(f"backend must be serial, processes or ray, got {self.kind!r}")
        if self.workers < 0:
            raise InputError(f"workers must be >= 1 (0: all cores), got {self.workers}")

    @classmethod
    def from_options(cls, workers: int = 1, ray: str | None = None) -> Backend:
        """The backend of the command-line options ``--workers N`` and ``--ray [ADDRESS]``.

        Args:
            workers: local worker processes (>= 1; 1 runs in this process).
            ray: ``None``: no Ray; ``""``: start a local Ray; else a cluster's address.

        Raises:
            InputError: ``workers`` < 1, or ``ray`` together with ``workers`` > 1.
            RayMissingError: ``ray`` given and Ray is not installed.
        """
        if workers < 1:
            raise InputError(f"--workers must be >= 1, got {workers}")
        if ray is not None:
            if workers > 1:
                raise InputError(
                    "--ray and --workers N > 1 exclude each other: Ray places the jobs on "
                    "its own workers; drop one of them"
                )
            import_ray()  # before any work: a missing extra is a one-line error
            return cls("ray", 0, ray or None)
        return cls("processes", workers) if workers > 1 else cls()

    def describe(self) -> str:
        """A short name for progress bars and logs, e.g. ``"2 processes"``."""
        if self.kind == "processes":
            return f"{self.workers} processes"
        if self.kind == "ray":
            return f"ray {self.address}" if self.address else "ray (local)"
        return "serial"


SERIAL = Backend()


def import_ray() -> Any:
    """The ``ray`` module.

    Raises:
        RayMissingError: Ray is not installed (:data:`RAY_MISSING`).
    """
    try:
        import ray
    except ImportError:
        raise RayMissingError(RAY_MISSING) from None
    return ray


# ---------------------------------------------------------------------------- in the workers
_RESOURCE: dict[Hashable, Any] = {}


def worker_resource(key: Hashable, build: Callable[[], T]) -> T:
    """The resource (e.g. ``(env, policy)``) of ``key`` in this process, built on first use.

    One resource is kept per process: a new key closes the previous one (everything in it
    with a ``close`` method). Jobs of the same spec in a row (a worker's share of a seed
    list) share one env; the env is reset by every episode's seed, so what ran in it before
    does not change an episode.

    Args:
        key: what identifies the resource (a job's spec).
        build: makes it.
    """
    if key not in _RESOURCE:
        release_worker_resources()
        _RESOURCE[key] = build()
    return _RESOURCE[key]


def prepare_here(key: Hashable, build: Callable[[], Any], backend: Backend) -> None:
    """Build a job's resource once in this process before any job runs: a bad env kwarg or
    a policy that does not fit fails here, at once and as itself, not in a worker after
    the pool has started. A serial run keeps it (its jobs use it); else it is released.

    Args:
        key: the resource's key (as the job passes it to :func:`worker_resource`).
        build: makes it.
        backend: where the jobs will run.
    """
    worker_resource(key, build)
    if backend.kind != "serial":
        release_worker_resources()


def release_worker_resources() -> None:
    """Close and forget this process's resource (a serial run calls it at its end)."""
    while _RESOURCE:
        _, value = _RESOURCE.popitem()
        for part in value if isinstance(value, tuple) else (value,):
            close = getattr(part, "close", None)
            if callable(close):
                close()


def limit_threads() -> None:
    """One native thread per worker: the thread variables, and torch's pool if loaded."""
    for name in THREAD_VARIABLES:
        os.environ[name] = "1"
    torch = sys.modules.get("torch")  # never imported here: only a job that needs it does
    if torch is not None and torch.get_num_threads() != 1:
        torch.set_num_threads(1)


_STARTED: Any = None  # the pool's shared "started" flags, one byte per item (per worker)


def _init_pool_worker(started: Any) -> None:
    global _STARTED
    _STARTED = started
    limit_threads()


def _pool_call(job: Callable[[Any], R], item: Any, index: int) -> R:
    _STARTED[index] = 1  # one byte, no lock: a worker killed right after cannot block others
    limit_threads()  # a job may have imported torch in the previous call
    return job(item)


def _ray_call(job: Callable[[Any], R], item: Any) -> R:
    limit_threads()
    return job(item)


# ---------------------------------------------------------------------------- the runner
@dataclass
class _Failure(Generic[T]):
    item: T
    reason: str


def run_jobs(
    job: Callable[[T], R],
    items: Sequence[T],
    backend: Backend = SERIAL,
    *,
    desc: str = "",
    progress: bool = False,
) -> list[R]:
    """``[job(item) for item in items]`` on ``backend``: see :func:`iter_jobs`.

    Raises:
        WorkerError: some jobs' workers died on every attempt (after all other jobs).
        Exception: what a job raised (at once).
    """
    return list(iter_jobs(job, items, backend, desc=desc, progress=progress))


def iter_jobs(
    job: Callable[[T], R],
    items: Sequence[T],
    backend: Backend = SERIAL,
    *,
    desc: str = "",
    progress: bool = False,
) -> Iterator[R]:
    """Yield ``job(item)`` for each item, in the items' order, computed on ``backend``.

    A result is yielded as soon as it and all results before it are in, so a caller that
    stores results (skill recording) keeps the finished ones if the run is interrupted.

    Args:
        job: a picklable callable (a module-level class or function) for ``processes`` and
            ``ray``; it must build what it needs itself (:func:`worker_resource`).
        items: what each call gets (seeds, or ``(class, seed)`` pairs); picklable.
        backend: where the jobs run (:class:`Backend`).
        desc: the progress bar's label.
        progress: show a tqdm progress bar on stderr.

    Yields:
        The jobs' results in the order of ``items`` (a job whose worker died on every
        attempt is left out and reported at the end).

    Raises:
        WorkerError: some jobs' workers died on every attempt (raised after every
            other result has been yielded; the message names their items).
        RayMissingError: a Ray backend without Ray installed.
        Exception: what a job raised, at once (the remaining jobs are cancelled).
    """
    items = list(items)
    label = f"{desc} [{backend.describe()}]" if desc and backend.kind != "serial" else desc
    # delay: no bar for what ends within a second (an error at the first job is one line)
    bar = tqdm(total=len(items), desc=label, unit="job", disable=not progress, delay=1.0)
    try:
        if backend.kind == "serial" or not items:
            try:
                for item in items:
                    result = job(item)
                    bar.update()
                    yield result
            finally:
                release_worker_resources()
            return
        run = _run_pool if backend.kind == "processes" else _run_ray
        results: dict[int, R | _Failure[T]] = {}
        failures: list[_Failure[T]] = []
        ready = 0
        for index, outcome in run(job, items, backend):
            results[index] = outcome
            bar.update()
            while ready in results:
                done = results.pop(ready)
                ready += 1
                if isinstance(done, _Failure):
                    failures.append(done)
                else:
                    yield done
    except BaseException:
        bar.leave = False  # an error's message is not preceded by a dead bar
        raise
    finally:
        bar.close()
    if failures:
        shown = ", ".join(repr(f.item) for f in failures)
        raise WorkerError(
            f"the worker running {shown} died on every attempt ({RETRIES + 1} attempts; "
            f"{failures[0].reason}); run {'it' if len(failures) == 1 else 'them'} alone "
            "(--workers 1) to see why",
            [f.item for f in failures],
        )


def _run_pool(
    job: Callable[[T], R], items: list[T], backend: Backend
) -> Iterator[tuple[int, R | _Failure[T]]]:
    """The process pool: yields ``(index, result)`` as jobs finish (see the module's Faults).

    Rounds: all jobs in a pool of ``backend.workers``; when it breaks, the jobs that had
    started and not finished are suspects (one attempt used), the others go to a new pool.
    Suspects then run alone, one after another in one-worker pools: a break there is that
    job's.
    """
    attempts = [0] * len(items)
    todo = list(range(len(items)))
    suspects: list[int] = []
    while todo or suspects:
        isolated = not todo
        batch = todo if todo else suspects
        workers = 1 if isolated else min(backend.workers or os.cpu_count() or 1, len(batch))
        broken: list[int] = []
        finished: set[int] = set()
        context = multiprocessing.get_context(START_METHOD)
        started = context.RawArray("b", len(items))  # the workers set their item's byte
        pool = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=context,
            initializer=_init_pool_worker,
            initargs=(started,),
        )
        try:
            # Isolated: one job per pool, so a pool's break is that one job's.
            futures: dict[Future[R], int] = {
                pool.submit(_pool_call, job, items[i], i): i
                for i in (batch[:1] if isolated else batch)
            }
            pending = set(futures)
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    index = futures[future]
                    try:
                        result = future.result()
                    except BrokenProcessPool:
                        broken.append(index)
                        continue
                    finished.add(index)
                    yield index, result
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
        if isolated:
            suspects = [i for i in suspects if i not in finished]
        else:
            todo = []
        # A pool that broke before any of its jobs started (a worker that cannot start)
        # blames them all: else they would be resubmitted for ever.
        blame_all = isolated or not any(started[i] for i in broken)
        for index in broken:
            if not (started[index] or blame_all):  # never ran: not its fault
                todo.append(index)
                continue
            attempts[index] += 1
            if attempts[index] > RETRIES:
                if index in suspects:
                    suspects.remove(index)
                yield index, _Failure(items[index], "the worker process was terminated")
            elif index not in suspects:
                suspects.append(index)
        todo.sort()


def _run_ray(
    job: Callable[[T], R], items: list[T], backend: Backend
) -> Iterator[tuple[int, R | _Failure[T]]]:
    """Ray tasks: yields ``(index, result)`` as tasks finish; Ray retries a task whose
    worker died (``max_retries``), a task that fails again is a :class:`_Failure`."""
    ray = import_ray()
    from ray.exceptions import RayTaskError

    started_here = not ray.is_initialized()
    if started_here:
        if backend.address:
            ray.init(address=backend.address, logging_level="WARNING")
        else:  # "local": a new local cluster, never one some other run left on this machine
            ray.init(
                address="local",
                num_cpus=backend.workers or os.cpu_count() or 1,
                include_dashboard=False,
                logging_level="WARNING",
            )
    try:
        remote = ray.remote(max_retries=RETRIES, retry_exceptions=False)(_ray_call)
        shared = ray.put(job)  # sent once, not with every task
        refs = {remote.remote(shared, item): i for i, item in enumerate(items)}
        pending = list(refs)
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    index = refs[ref]
                    try:
                        result = ray.get(ref)
                    except RayTaskError as exc:  # the job raised: raise it as in a serial run
                        cause = exc.cause if isinstance(exc.cause, BaseException) else exc
                        raise cause from None
                    except ray.exceptions.RayError as exc:  # the worker died (and again)
                        reason = " ".join(str(exc).split())[:200]
                        yield index, _Failure(items[index], f"{type(exc).__name__}: {reason}")
                        continue
                    yield index, result
        finally:
            for ref in pending:
                ray.cancel(ref, force=True)
    finally:
        if started_here:
            ray.shutdown()


__all__ = [
    "RAY_MISSING",
    "RETRIES",
    "SERIAL",
    "START_METHOD",
    "THREAD_VARIABLES",
    "Backend",
    "RayMissingError",
    "WorkerError",
    "import_ray",
    "iter_jobs",
    "limit_threads",
    "prepare_here",
    "release_worker_resources",
    "run_jobs",
    "worker_resource",
]
