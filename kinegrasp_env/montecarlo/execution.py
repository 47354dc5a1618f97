"""Where tasks run: a process pool on this machine (default) or a Ray cluster.

An :class:`Executor` runs a module-level function over a list of picklable tasks and yields
the results either in task order (:meth:`Executor.map`) or as they finish
(:meth:`Executor.as_completed`). Results never depend on the backend: every task carries
its own identity (its random rows are derived from the run seed and that identity, see
:mod:`kinegrasp_env.montecarlo.chunks`), and callers merge results in task order.

Failures: a worker process that dies (killed, out of memory, a crash in a native library)
loses only the tasks it held. The local pool is rebuilt and those tasks are submitted again;
Ray re-runs them itself (``max_retries``). A task that kills its worker
:data:`MAX_ATTEMPTS` times is reported as an error, not retried forever.
"""

from __future__ import annotations

import os
import sys
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from kinegrasp_env.counts import check_count

BACKENDS = ("local", "ray")
#: Engines a process keeps between tasks (the oldest is closed when one more is needed: a
#: pybullet engine holds a simulator client and tens of MB).
MAX_ENGINES = 4
#: How often one task may take its worker down before the run gives up.
MAX_ATTEMPTS = 4
#: Tasks in flight per worker (keeps workers busy without queueing the whole run).
IN_FLIGHT_PER_WORKER = 2


class Executor:
    """Runs ``fn(task)`` for every task; subclasses say where.

    Use as a context manager (or call :meth:`close`): pools and Ray connections live for
    the executor's lifetime, so engines built inside workers are reused across calls.
    """

    workers: int = 1
    description: str = ""

    def map(self, fn: Callable[[Any], Any], tasks: Iterable[Any]) -> Iterator[Any]:
        """Results of ``fn(task)`` in task order."""
        for _, result in self._run(fn, list(tasks), ordered=True):
            yield result

    def as_completed(self, fn: Callable[[Any], Any],
                     tasks: Iterable[Any]) -> Iterator[tuple[int, Any]]:
        """``(task index, result)`` pairs as tasks finish."""
        yield from self._run(fn, list(tasks), ordered=False)

    def _run(self, fn: Callable[[Any], Any], tasks: list[Any],
             ordered: bool) -> Iterator[tuple[int, Any]]:
        submitted = done = emitted = 0
        buffered: dict[int, Any] = {}
        window = max(1, self.workers * IN_FLIGHT_PER_WORKER)
        try:
            while done < len(tasks):
                while submitted < len(tasks) and submitted - done < window:
                    self._submit(fn, submitted, tasks[submitted])
                    submitted += 1
                index, result = self._collect(fn)
                done += 1
                if not ordered:
                    yield index, result
                    continue
                buffered[index] = result
                while emitted in buffered:
                    yield emitted, buffered.pop(emitted)
                    emitted += 1
        finally:
            self._cancel()

    # backend hooks -------------------------------------------------------------------
    def _submit(self, fn: Callable[[Any], Any], index: int, task: Any) -> None:
        raise NotImplementedError

    def _collect(self, fn: Callable[[Any], Any]) -> tuple[int, Any]:
        raise NotImplementedError

    def _cancel(self) -> None:
        """Forget tasks still in flight (the caller stopped early or failed)."""

    def close(self) -> None:
        """Release workers; the executor cannot be used afterwards."""

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def leave_signals_to_the_parent() -> None:
    """A worker process's start: Ctrl-C (SIGINT, which a terminal sends to every process of
    the job) is the parent's to handle (it stops the pool; a worker interrupted in the
    middle of a task would print its traceback), and SIGTERM ends the worker plainly (not
    through a handler it inherited)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


class LocalExecutor(Executor):
    """``processes`` worker processes on this machine (1: run inline, no pool)."""

    def __init__(self, processes: int = 1):
        self.workers = check_count(processes, "processes")
        self.description = f"local, {self.workers} process{'es' if self.workers > 1 else ''}"
        self._pool: ProcessPoolExecutor | None = None
        self._inline: deque[tuple[int, Any]] = deque()
        self._futures: dict[Future, tuple[int, Any]] = {}
        self._attempts: dict[int, int] = {}

    def _pool_now(self) -> ProcessPoolExecutor:
        if self._pool is None:
            import multiprocessing

            method = "fork" if sys.platform == "linux" else "spawn"
            self._pool = ProcessPoolExecutor(max_workers=self.workers,
                                             mp_context=multiprocessing.get_context(method),
                                             initializer=leave_signals_to_the_parent)
        return self._pool

    def _submit(self, fn, index, task) -> None:
        if self.workers == 1:
            self._inline.append((index, task))
            return
        try:
            future = self._pool_now().submit(fn, task)
        except BrokenProcessPool:  # a worker died since the last submission
            self._restart(fn, [(index, task)])
            return
        self._attempts[index] = self._attempts.get(index, 0) + 1
        self._futures[future] = (index, task)

    def _collect(self, fn) -> tuple[int, Any]:
        if self.workers == 1:
            index, task = self._inline.popleft()
            return index, fn(task)
        while True:
            finished, _ = wait(list(self._futures), return_when=FIRST_COMPLETED)
            future = next(iter(finished))
            index, task = self._futures.pop(future)
            try:
                result = future.result()
            except BrokenProcessPool:
                self._restart(fn, [(index, task)])
                continue
            self._attempts.pop(index, None)
            return index, result

    def _restart(self, fn, lost: list[tuple[int, Any]]) -> None:
        """A worker died: the tasks in flight go to a fresh pool (which one killed the
        worker is unknown, so each counts an attempt)."""
        lost = [*lost, *self._futures.values()]
        self._futures.clear()
        self._pool.shutdown(wait=False, cancel_futures=True)
        self._pool = None
        for i, t in lost:
            if self._attempts.get(i, 0) >= MAX_ATTEMPTS:
                raise RuntimeError(f"task {i} was in flight when a worker process died "
                                   f"{MAX_ATTEMPTS} times; giving up")
            print(f"kinegrasp: a worker process died; re-running task {i}", file=sys.stderr)
            self._submit(fn, i, t)

    def _cancel(self) -> None:
        self._inline.clear()
        for future in self._futures:
            future.cancel()
        self._futures.clear()
        self._attempts.clear()

    def close(self) -> None:
        self._cancel()
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def __exit__(self, exc_type, *exc) -> None:
        if exc_type is not None:
            self.stop_workers()
        self.close()

    def stop_workers(self) -> None:
        """End the pool's worker processes now (SIGTERM): a run stopped by Ctrl-C or an error
        needs none of their results, and a pool shut down after a signal interrupted its own
        hand-over (the call queue's feeder) can leave workers waiting on that queue, and the
        shut-down and the exit waiting on them, forever (seen after about 1 Ctrl-C in 6)."""
        processes = getattr(self._pool, "_processes", None) or {}
        for process in list(processes.values()):
            process.terminate()


def _import_ray():
    try:
        import ray
    except ImportError:
        raise ValueError("the ray backend needs Ray, which is not installed: "
                         "pip install 'kinegrasp-env[ray]'") from None
    return ray


def _check_reachable(address: str, timeout: float = 5.0) -> None:
    """Fail fast on an unreachable ``host:port`` (``ray.init`` would wait for minutes)."""
    import socket

    host_port = address.split("://", 1)[-1]
    if host_port == "auto":
        return
    host, _, port = host_port.rpartition(":")
    if not host or not port.isdigit():
        raise ValueError(f"--address must be host:port or ray://host:port (or auto), got "
                         f"{address!r}")
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as exc:
        raise ValueError(f"cannot reach a Ray cluster at {address!r}: {exc}") from None


class RayExecutor(Executor):
    """Tasks as Ray remote functions (one CPU each).

    Args:
        address: a running cluster (``ray://host:10001`` or ``host:6379``, as
            ``ray.init`` takes it); ``None`` starts a local Ray instance for the
            executor's lifetime.
        num_cpus: CPUs of that local instance, an integer >= 1 (default: all of this
            machine's).
        max_retries: re-runs of a task whose worker or node died.
    """

    def __init__(self, address: str | None = None, num_cpus: int | None = None,
                 max_retries: int = MAX_ATTEMPTS - 1):
        if num_cpus is not None:
            num_cpus = check_count(num_cpus, "num_cpus")
        ray = _import_ray()
        if address is not None:
            _check_reachable(address)
        self._ray = ray
        self._owns = False
        if not ray.is_initialized():
            import logging

            options: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                                       "logging_level": logging.WARNING}
            if address is None:
                options["num_cpus"] = num_cpus or os.cpu_count() or 1
            try:
                ray.init(address=address, **options)
            except ConnectionError as exc:
                raise ValueError(f"cannot reach a Ray cluster at {address!r}: {exc}") from None
            self._owns = True
        self.workers = max(1, int(ray.cluster_resources().get("CPU", 1)))
        where = address or "a local Ray instance"
        self.description = f"ray ({where}, {self.workers} CPUs)"
        self._max_retries = int(max_retries)
        self._remote: dict[Callable, Any] = {}
        self._refs: dict[Any, int] = {}

    def _submit(self, fn, index, task) -> None:
        remote = self._remote.get(fn)
        if remote is None:
            remote = self._remote[fn] = self._ray.remote(num_cpus=1,
                                                         max_retries=self._max_retries)(fn)
        self._refs[remote.remote(task)] = index

    def _collect(self, fn) -> tuple[int, Any]:
        ready, _ = self._ray.wait(list(self._refs), num_returns=1)
        index = self._refs.pop(ready[0])
        return index, self._ray.get(ready[0])

    def _cancel(self) -> None:
        for ref in self._refs:
            self._ray.cancel(ref, force=True)
        self._refs.clear()

    def close(self) -> None:
        self._cancel()
        if self._owns and self._ray.is_initialized():
            self._ray.shutdown()
            self._owns = False


def make_executor(backend: str = "local", processes: int | None = None,
                  address: str | None = None) -> Executor:
    """The executor for ``--backend``/``--processes``/``--address``.

    ``processes`` is the number of local worker processes (default 1) or, for ``ray``
    without an address, the CPUs of the local Ray instance (default: all).
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose from {', '.join(BACKENDS)}")
    if processes is not None:
        processes = check_count(processes, "processes")
    if backend == "local":
        if address is not None:
            raise ValueError("--address is for the ray backend (add --backend ray)")
        return LocalExecutor(processes or 1)
    return RayExecutor(address=address, num_cpus=processes)
