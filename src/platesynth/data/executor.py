"""Where batch work runs: in this process, in local worker processes, or on a Dask cluster.

An executor knows nothing of rendering or files: it runs a picklable ``task(item) -> record`` over items and
yields the records as they finish (in any order). Workers may run a ``setup()`` once when they start (e.g. to
start a long-lived renderer process); the callable must be picklable (a module-level function).

Use them as context managers::

    with ProcessExecutor(workers=4) as executor:
        for record in executor.map_unordered(task, range(100)):
            ...
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import functools
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from platesynth.errors import ExecutorError, ParameterError

T = TypeVar("T")
R = TypeVar("R")

EXECUTORS = ("local", "dask")


class SerialExecutor:
    """Runs every task in this process, one after the other."""

    def __init__(self, setup: Callable[[], None] | None = None) -> None:
        self._setup = setup

    def __enter__(self) -> SerialExecutor:
        if self._setup is not None:
            self._setup()
        return self

    def __exit__(self, *exc_info: object) -> None:
        return None

    def map_unordered(self, task: Callable[[T], R], items: Iterable[T]) -> Iterator[R]:
        """Yield ``task(item)`` for every item, in order."""
        for item in items:
            yield task(item)

    def describe(self) -> str:
        """A short description for people, e.g. ``"1 process"``."""
        return "1 process"


THREAD_VARIABLES = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
"""The environment variables that size the thread pools of numba, OpenMP and the BLAS libraries."""


def limit_threads(threads: int) -> None:
    """Let the thread pools of this process use ``threads`` threads, where the environment does not say otherwise.

    Sets the variables of :data:`THREAD_VARIABLES` that are unset, for the libraries imported later; numba, if
    already imported, reads its variable again when it compiles and refuses a new value once its threads run, so
    then its thread count is set instead (unless ``NUMBA_NUM_THREADS`` is set).
    """
    numba = sys.modules.get("numba")
    if numba is not None and "NUMBA_NUM_THREADS" not in os.environ:
        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    for name in THREAD_VARIABLES:
        if not (name == "NUMBA_NUM_THREADS" and numba is not None):
            os.environ.setdefault(name, str(threads))


PR_SET_PDEATHSIG = 1  # linux/prctl.h


def end_with_parent(parent: int) -> None:
    """Make this process end when its parent process ``parent`` ends, however that ends (even by SIGKILL).

    On Linux the kernel sends SIGTERM when the parent dies (``prctl(PR_SET_PDEATHSIG)``); elsewhere a daemon thread
    checks the parent every second. A parent already gone ends this process at once.
    """
    armed = False
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0) == 0
        except (OSError, AttributeError):
            armed = False
    if os.getppid() != parent:  # the parent ended before the signal was armed
        os._exit(1)
    if not armed:
        threading.Thread(target=_watch_parent, args=(parent,), name="platesynth-parent-watch", daemon=True).start()


def _watch_parent(parent: int) -> None:
    while True:
        time.sleep(1.0)
        if os.getppid() != parent:
            os._exit(1)


def _start_worker(threads: int, setup: Callable[[], None] | None, parent: int | None = None) -> None:
    """Initializer of a :class:`ProcessExecutor` worker: it ends with its parent, gets its share of the CPUs and a
    quick exit, then runs the caller's setup."""
    if parent is not None:
        end_with_parent(parent)
    limit_threads(threads)
    atexit.register(_exit_now)  # registered first, so it runs after the other exit handlers (e.g. the setup's)
    if setup is not None:
        setup()


def _exit_now() -> None:
    """End a worker process once its exit handlers have run, without tearing down its modules one by one.

    With numba, LLVM and scipy loaded that took 0.3-0.6 s per worker, and the pool waits for its workers to exit.
    The worker's files are all written and renamed by then, and its results sent.
    """
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(0)


class ProcessExecutor:
    """Runs tasks in ``workers`` local processes started with ``spawn`` (safe with threads, same on every OS).

    At most ``2 * workers`` tasks are queued at a time, so an interrupt stops the batch quickly. Workers end with
    this process, however it ends (:func:`end_with_parent`). The CPUs are
    shared among the workers: each one's numba, OpenMP and BLAS thread pools get ``threads_per_worker`` threads
    (default: the CPUs this process may use divided by ``workers``, at least 1), unless the environment sets
    them (:data:`THREAD_VARIABLES`). Without this every worker's pool had a thread per CPU, and the threads of
    the workers competed for the same CPUs.
    """

    def __init__(
        self, workers: int, setup: Callable[[], None] | None = None, threads_per_worker: int | None = None
    ) -> None:
        if workers < 1:
            raise ParameterError(f"workers must be >= 1, got {workers}")
        if threads_per_worker is not None and threads_per_worker < 1:
            raise ParameterError(f"threads_per_worker must be >= 1, got {threads_per_worker}")
        self.workers = workers
        self.threads_per_worker = threads_per_worker or max(1, default_workers() // workers)
        self._setup = setup
        self._pool: ProcessPoolExecutor | None = None

    def __enter__(self) -> ProcessExecutor:
        self._pool = ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=functools.partial(_start_worker, self.threads_per_worker, self._setup, os.getpid()),
        )
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *exc_info: object) -> None:
        if self._pool is None:
            return
        if exc_type is not None:
            # interrupted or failed: stop the workers now instead of waiting for their current items; what they
            # were writing is left under temporary names, which the next run removes
            for process in list(getattr(self._pool, "_processes", {}).values()):
                process.terminate()
        self._pool.shutdown(wait=True, cancel_futures=True)
        self._pool = None

    def map_unordered(self, task: Callable[[T], R], items: Iterable[T]) -> Iterator[R]:
        """Yield ``task(item)`` for every item as the workers finish them."""
        if self._pool is None:
            raise RuntimeError("use ProcessExecutor as a context manager")
        pending: set[Future[R]] = set()
        queue = iter(items)
        try:
            while True:
                for item in queue:
                    pending.add(self._pool.submit(task, item))
                    if len(pending) >= 2 * self.workers:
                        break
                if not pending:
                    return
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    yield future.result()
        except BrokenProcessPool as exc:
            message = f"a worker process died unexpectedly ({exc}); run the command again to resume"
            raise ExecutorError(message) from None
        finally:
            for future in pending:
                future.cancel()

    def describe(self) -> str:
        """A short description for people, e.g. ``"4 processes"``."""
        return f"{self.workers} processes"


class DaskExecutor:
    """Runs tasks on a Dask cluster: an existing scheduler (``scheduler`` address) or a new ``LocalCluster``.

    Parameters
    ----------
    scheduler : str, optional
        Address of a running scheduler (``tcp://host:8786``). Default: start a ``LocalCluster`` of ``workers``
        single-threaded processes for the lifetime of the executor.
    workers : int
        Number of workers of the ``LocalCluster`` (ignored with ``scheduler``).
    setup : callable, optional
        Run once on every worker before its first task.
    timeout : float
        Seconds to wait for the scheduler before giving up.

    Notes
    -----
    The workers write the files themselves, so with a remote cluster the output directory must be on a
    file system that every worker sees under the same path (e.g. the shared file system of an HPC cluster).
    """

    def __init__(
        self,
        scheduler: str | None = None,
        workers: int = 1,
        setup: Callable[[], None] | None = None,
        timeout: float = 10.0,
    ) -> None:
        if workers < 1:
            raise ParameterError(f"workers must be >= 1, got {workers}")
        if timeout <= 0:
            raise ParameterError(f"timeout must be > 0 seconds, got {timeout}")
        self.scheduler = scheduler
        self.workers = workers
        self.timeout = timeout
        self._setup = setup
        self._cluster: Any = None
        self._client: Any = None

    def __enter__(self) -> DaskExecutor:
        try:
            from distributed import Client, LocalCluster

            from platesynth.data._dask_plugin import SetupPlugin
        except ImportError:
            raise ExecutorError("the dask executor needs dask.distributed: pip install 'platesynth[dask]'") from None
        try:
            if self.scheduler is None:
                self._cluster = LocalCluster(
                    n_workers=self.workers,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    scheduler_kwargs={"dashboard_address": ":0"},  # its HTTP server on a free port, not 8787
                )
                self._client = Client(self._cluster, timeout=f"{self.timeout}s")
            else:
                self._client = Client(self.scheduler, timeout=f"{self.timeout}s")
        except (OSError, TimeoutError, ValueError, RuntimeError) as exc:
            self.__exit__()
            where = self.scheduler or "a local Dask cluster"
            raise ExecutorError(f"cannot connect to Dask scheduler {where}: {exc}") from None
        if self._setup is not None:
            self._client.register_plugin(SetupPlugin(self._setup), name="platesynth-setup")
        return self

    def __exit__(self, *exc_info: object) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def map_unordered(self, task: Callable[[T], R], items: Iterable[T]) -> Iterator[R]:
        """Yield ``task(item)`` for every item as the cluster finishes them."""
        if self._client is None:
            raise RuntimeError("use DaskExecutor as a context manager")
        from distributed import as_completed

        futures = self._client.map(task, list(items), pure=False)
        try:
            for future in as_completed(futures):
                yield future.result()
        finally:
            self._client.cancel([f for f in futures if not f.done()])

    def describe(self) -> str:
        """A short description for people."""
        if self.scheduler is not None:
            return f"Dask cluster at {self.scheduler}"
        return f"local Dask cluster of {self.workers} workers"


Executor = SerialExecutor | ProcessExecutor | DaskExecutor


def make_executor(
    kind: str = "local",
    workers: int = 1,
    scheduler: str | None = None,
    setup: Callable[[], None] | None = None,
    timeout: float = 10.0,
) -> Executor:
    """The executor a command line asks for.

    Parameters
    ----------
    kind : {"local", "dask"}
        ``local``: this process when ``workers == 1``, else ``workers`` local processes. ``dask``: the
        cluster at ``scheduler``, or a new LocalCluster of ``workers`` processes.
    workers, scheduler, setup, timeout
        See :class:`ProcessExecutor` and :class:`DaskExecutor`.

    Raises
    ------
    ParameterError
        For an unknown kind, ``workers < 1``, or a scheduler given to the local executor.
    """
    if kind not in EXECUTORS:
        raise ParameterError(f"unknown executor {kind!r} (choose from {', '.join(EXECUTORS)})")
    if workers < 1:
        raise ParameterError(f"workers must be >= 1, got {workers}")
    if kind == "dask":
        return DaskExecutor(scheduler=scheduler, workers=workers, setup=setup, timeout=timeout)
    if scheduler is not None:
        raise ParameterError("a scheduler address needs the dask executor (--executor dask)")
    if workers == 1:
        return SerialExecutor(setup=setup)
    return ProcessExecutor(workers=workers, setup=setup)


def default_workers() -> int:
    """The number of CPUs this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
