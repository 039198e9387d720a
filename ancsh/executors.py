"""Where independent tasks run: worker processes on this machine, or a Ray cluster.

The jobs that fan out over frames or objects (``ancsh data generate``, ``ancsh evaluate``,
``ancsh evaluate-cad``) hand their tasks to an :class:`Executor` and consume the results **in task
order**. Each job gives a *worker factory* ``make_worker(*args) -> worker`` (a picklable module-level
callable); every worker process builds one worker (models, renderers and networks cached inside it)
and calls ``worker(task)`` for each task it receives. Because every task is a pure function of the
job's settings and its own index (frames are seeded per frame index), the results -- and so the
files and tables a job writes -- do not depend on the executor or the number of workers.

- :class:`LocalExecutor` (the default): ``workers=1`` runs in this process; more workers are
  ``spawn``-ed processes (:class:`concurrent.futures.ProcessPoolExecutor`).
- :class:`RayExecutor`: one Ray actor per worker, on the cluster at ``address`` or on a local Ray
  started (and shut down) for the job. A worker process that dies is restarted and its task run
  again, up to ``max_retries`` times (tasks are idempotent).

When a worker dies and is not retried, the job sees :class:`WorkerLost`; what it had completed
stays complete (``generate_dataset`` writes every shard atomically, and a rerun resumes).

Ray is an optional dependency (``pip install 'ancsh[ray]'``), imported only when a
:class:`RayExecutor` runs.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

__all__ = [
    "EXECUTORS",
    "Executor",
    "LocalExecutor",
    "RayExecutor",
    "WorkerLost",
    "make_executor",
    "ray_available",
]

EXECUTORS = ("local", "ray")
"""Executor kinds (``--executor`` values)."""

RAY_MISSING = "Ray is not installed; install it with: pip install 'ancsh[ray]'"


class WorkerLost(RuntimeError):
    """A worker process died (killed, out of memory, node lost) and its task was not retried."""


@dataclass(frozen=True)
class LocalExecutor:
    """Tasks in this process (``workers=1``) or in ``workers`` spawned processes of this machine.

    Attributes
    ----------
    workers : int
        ``>= 1``.
    in_process : bool
        With one worker, run the tasks in this process (the default); ``False`` spawns one process
        (what a benchmark compares with more workers).
    """

    workers: int = 1
    in_process: bool = True

    def __post_init__(self):
        _check_workers(self.workers)

    @property
    def kind(self) -> str:
        return "local"

    def describe(self) -> str:
        if self.workers == 1:
            return "in this process" if self.in_process else "1 local process"
        return f"{self.workers} local processes"

    def session(self):
        """A context for several :meth:`imap` calls (nothing to set up for local processes)."""
        return contextlib.nullcontext(self)

    def imap(self, make_worker: Callable, args: tuple, tasks: Iterable) -> Iterator:
        """Yield ``worker(task)`` for every task, in task order (see the module docstring).

        With one worker the tasks run lazily in this process: stopping the iteration stops the work.
        With more, all tasks are submitted; stopping the iteration cancels those not started.

        Raises
        ------
        WorkerLost
            When a worker process dies.
        """
        tasks = list(tasks)
        if not tasks:
            return
        if self.workers == 1 and self.in_process:
            worker = make_worker(*args)
            for task in tasks:
                yield worker(task)
            return
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor
        from concurrent.futures.process import BrokenProcessPool

        # "spawn": workers never inherit open3d/OpenMP thread state from the parent.
        pool = ProcessPoolExecutor(max_workers=min(self.workers, len(tasks)), mp_context=mp.get_context("spawn"),
                                   initializer=_init_local_worker, initargs=(make_worker, args, os.getpid()))
        try:
            for future in [pool.submit(_run_local_task, task) for task in tasks]:
                try:
                    yield future.result()
                except BrokenProcessPool as exc:
                    raise WorkerLost(f"a local worker process died ({exc}); completed results are kept") from None
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


_LOCAL_WORKER = None


PARENT_POLL_S = 0.5
"""How often a local worker checks that the process that started it is alive."""


def exit_with_parent(parent_pid: int, poll_s: float = PARENT_POLL_S) -> threading.Thread:
    """Start a daemon thread that ends this process once ``parent_pid`` is no longer its parent.

    A worker whose parent was killed (SIGKILL leaves no chance to stop the pool) is re-parented; the
    thread notices within ``poll_s`` seconds and exits the process at once (``os._exit``: the parent
    that would read its results is gone).
    """
    def watch():
        while os.getppid() == parent_pid:
            time.sleep(poll_s)
        os._exit(1)

    thread = threading.Thread(target=watch, name="exit-with-parent", daemon=True)
    thread.start()
    return thread


def _init_local_worker(make_worker: Callable, args: tuple, parent_pid: int | None = None) -> None:
    global _LOCAL_WORKER
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    if parent_pid is not None:
        exit_with_parent(parent_pid)
    _LOCAL_WORKER = make_worker(*args)


def _run_local_task(task):
    return _LOCAL_WORKER(task)


@dataclass(frozen=True)
class RayExecutor:
    """Tasks on Ray actors: ``workers`` of them, one CPU each.

    Attributes
    ----------
    workers : int
        Actors (worker processes), ``>= 1``.
    address : str or None
        Address of a running Ray cluster (``"auto"``, ``"ray://head:10001"``, ``"10.0.0.1:6379"``);
        ``None`` starts a local Ray with ``workers`` CPUs for the job (no dashboard) and shuts it
        down afterwards. A Ray already initialised in this process is used as it is.
    max_retries : int
        Restarts of a dead worker, each re-running its unfinished tasks (``0`` = none: the job
        raises :class:`WorkerLost`).
    """

    workers: int = 1
    address: str | None = None
    max_retries: int = 3

    def __post_init__(self):
        _check_workers(self.workers)
        if isinstance(self.max_retries, bool) or not isinstance(self.max_retries, int) or self.max_retries < 0:
            raise ValueError(f"max_retries: expected an int >= 0, got {self.max_retries!r}")
        if self.address is not None and (not isinstance(self.address, str) or not self.address.strip()):
            raise ValueError(f"address: expected a Ray address such as 'auto' or 'ray://head:10001', got {self.address!r}")

    @property
    def kind(self) -> str:
        return "ray"

    def describe(self) -> str:
        where = f"the Ray cluster at {self.address}" if self.address else "a local Ray"
        return f"{self.workers} Ray worker(s) on {where}"

    @contextlib.contextmanager
    def session(self):
        """Connect to Ray (or start a local one) for several :meth:`imap` calls; disconnect at the end if
        this call connected (each :meth:`imap` alone connects and disconnects otherwise)."""
        ray = import_ray()
        started = start_ray(ray, address=self.address, num_cpus=self.workers)
        try:
            yield self
        finally:
            if started:
                ray.shutdown()

    def imap(self, make_worker: Callable, args: tuple, tasks: Iterable) -> Iterator:
        """As :meth:`LocalExecutor.imap`, on Ray actors (tasks go to whichever actor is free)."""
        tasks = list(tasks)
        if not tasks:
            return
        ray = import_ray()
        started = start_ray(ray, address=self.address, num_cpus=self.workers)
        actors = []
        try:
            options = dict(num_cpus=1, max_restarts=self.max_retries, max_task_retries=self.max_retries)
            actor_class = ray.remote(**options)(_RayWorker)
            actors = [actor_class.remote(make_worker, args) for _ in range(min(self.workers, len(tasks)))]
            yield from _ordered_results(ray, actors, tasks)
        finally:
            for actor in actors:
                ray.kill(actor)
            if started:
                ray.shutdown()


class _RayWorker:
    """The Ray actor: one worker built by ``make_worker(*args)``, called once per task."""

    def __init__(self, make_worker: Callable, args: tuple):
        self._worker = make_worker(*args)

    def run(self, task):
        return self._worker(task)


def _ordered_results(ray, actors: list, tasks: list) -> Iterator:
    """Results of ``tasks`` in order. Each actor holds at most two unfinished tasks (one running, one
    queued); a finished task frees its actor at once, even while an earlier task is still running (at most
    ``4 * len(actors)`` tasks ahead of the one being read)."""
    refs: dict = {}  # task index -> object ref (in flight or finished)
    running: dict = {}  # object ref -> actor, unfinished
    load = {id(a): 0 for a in actors}
    next_task = 0

    def fill(first_unread: int):
        nonlocal next_task
        while next_task < min(len(tasks), first_unread + 4 * len(actors)):  # bounded read-ahead
            actor = min(actors, key=lambda a: load[id(a)])
            if load[id(actor)] >= 2:
                return
            load[id(actor)] += 1
            ref = actor.run.remote(tasks[next_task])
            refs[next_task], running[ref] = ref, actor
            next_task += 1

    for i in range(len(tasks)):
        fill(i)
        while refs[i] in running:  # wait for task i, giving actors new work as their tasks finish
            ready, _ = ray.wait(list(running), num_returns=1)
            for ref in ready:
                load[id(running.pop(ref))] -= 1
            fill(i)
        try:
            result = ray.get(refs.pop(i))
        except ray.exceptions.RayActorError as exc:
            raise WorkerLost(f"a Ray worker died and was not restarted ({str(exc).splitlines()[0]}); "
                             "completed results are kept") from None
        yield result


def ray_available() -> bool:
    """Whether Ray can be imported (without importing it)."""
    import importlib.util

    return importlib.util.find_spec("ray") is not None


def import_ray():
    """The ``ray`` module; ImportError with the install command when it is missing."""
    try:
        import ray
    except ImportError:
        raise ImportError(RAY_MISSING) from None
    return ray


def start_ray(ray, *, address: str | None, num_cpus: int) -> bool:
    """Connect to Ray unless this process already is; returns whether this call started the connection
    (the caller then shuts it down). Without ``address``, a local Ray with ``num_cpus`` CPUs and no dashboard."""
    if ray.is_initialized():
        return False
    if address:
        probe_ray_address(address)
        ray.init(address=address, log_to_driver=True)
    else:
        ray.init(num_cpus=int(num_cpus), include_dashboard=False, log_to_driver=True)
    return True


RAY_CONNECT_TIMEOUT_S = 5.0
"""How long :func:`probe_ray_address` waits for a cluster's port to answer (Ray itself retries for minutes)."""


def probe_ray_address(address: str, timeout_s: float = RAY_CONNECT_TIMEOUT_S) -> None:
    """Refuse a Ray address where nothing listens, before ``ray.init`` retries it for minutes.

    ``"auto"`` / ``"local"`` are left to Ray (it fails at once when no cluster runs here); ``host:port``
    (the cluster's GCS) and ``ray://host:port`` (Ray Client) must accept a TCP connection within
    ``timeout_s`` seconds.

    Raises
    ------
    ValueError
        An address without a port.
    ConnectionError
        Nothing answers there, naming the address.
    """
    import socket

    if address in ("auto", "local"):
        return
    hostport = address[len("ray://"):] if address.startswith("ray://") else address
    host, sep, port = hostport.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise ValueError(f"address: expected 'auto', 'host:port' or 'ray://host:port', got {address!r}")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s):
            pass
    except OSError as exc:
        raise ConnectionError(f"address: no Ray cluster answers at {address} within {timeout_s:g} s "
                              f"({exc.strerror or type(exc).__name__}); start one there (ray start --head) or leave "
                              "the address out for a local Ray") from None


def _check_workers(workers) -> None:
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers: expected an int >= 1, got {workers!r}")


Executor = LocalExecutor | RayExecutor
"""Either executor (both have ``workers``, ``kind``, ``describe()``, ``session()`` and ``imap(make_worker, args, tasks)``)."""


def make_executor(kind: str = "local", workers: int = 1, *, address: str | None = None, max_retries: int = 3):
    """An executor by name (``kind`` in :data:`EXECUTORS`).

    Raises
    ------
    ValueError
        For an unknown kind, an address without Ray, or ``kind="ray"`` when Ray is not installed.
    """
    if kind not in EXECUTORS:
        raise ValueError(f"executor: expected one of {EXECUTORS}, got {kind!r}")
    if kind == "local":
        if address is not None:
            raise ValueError("ray_address: only with the ray executor")
        return LocalExecutor(int(workers))
    if not ray_available():
        raise ValueError(f"executor ray: {RAY_MISSING}")
    return RayExecutor(int(workers), address=address, max_retries=max_retries)
