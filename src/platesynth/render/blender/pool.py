"""Host side of the Blender backend: long-lived Blender worker processes, per-image timeouts, retries.

A worker is ``python -m platesynth.render.blender.worker``: it imports ``bpy`` once and then serves requests
(one JSON line in on stdin, one JSON line out on stdout) until it is told to quit. Blender's own output goes to a
per-worker log file, whose tail is attached to the error when a worker crashes or hangs. Workers are replaced
every ``max_renders_per_worker`` requests to bound memory (long Blender loops leak).
"""

from __future__ import annotations

import atexit
import itertools
import json
import os
import queue
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from platesynth.errors import ParameterError, RenderError

LOG_TAIL_CHARS = 6000


class BlenderScriptError(RenderError):
    """Python code inside Blender raised: a deterministic failure, not retried.

    Attributes
    ----------
    log : str
        Blender's log for this request, with the traceback from inside Blender.
    """

    def __init__(self, message: str, log: str = "") -> None:
        super().__init__(message)
        self.log = log


class BlenderWorkerError(RenderError):
    """A Blender worker crashed or timed out on every attempt (the first try and the retries).

    Attributes
    ----------
    log : str
        The tail of Blender's log of the last attempt.
    attempts : list of str
        One line per attempt saying what went wrong.
    """

    def __init__(self, message: str, log: str = "", attempts: list[str] | None = None) -> None:
        super().__init__(message)
        self.log = log
        self.attempts = attempts or []


class _WorkerLost(Exception):
    """The worker died or hung during a request (internal: the pool retries, then raises BlenderWorkerError)."""

    def __init__(self, reason: str, log: str) -> None:
        last_lines = [line.strip() for line in log.splitlines() if line.strip()]
        if last_lines:
            reason = f"{reason}; Blender's last words: {last_lines[-1][:200]}"
        super().__init__(reason)
        self.reason = reason
        self.log = log


def platesynth_cache_dir() -> Path:
    """The directory platesynth owns for caches: ``$PLATESYNTH_CACHE_DIR``, else ``$XDG_CACHE_HOME/platesynth``,
    else ``~/.cache/platesynth``."""
    if os.environ.get("PLATESYNTH_CACHE_DIR"):
        return Path(os.environ["PLATESYNTH_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "platesynth"


def blender_home() -> Path:
    """Where Blender's home-directory files (``~/.config/blender``, caches) go instead of the user's home."""
    return platesynth_cache_dir() / "blender-home"


def worker_environment(home: Path) -> dict[str, str]:
    """The environment of a worker process: the caller's, with HOME and the XDG directories under ``home``."""
    env = dict(os.environ)
    env.update(
        HOME=str(home),
        XDG_CONFIG_HOME=str(home / ".config"),
        XDG_CACHE_HOME=str(home / ".cache"),
        XDG_DATA_HOME=str(home / ".local" / "share"),
        PYTHONUNBUFFERED="1",
    )
    return env


def default_worker_command() -> list[str]:
    """The command line that starts one worker with this interpreter."""
    return [sys.executable, "-m", "platesynth.render.blender.worker"]


class _Worker:
    """One worker process: a pipe for requests and replies, a log file for everything Blender prints."""

    def __init__(self, command: list[str], env: dict[str, str], log_path: Path) -> None:
        self.log_path = log_path
        self.renders = 0
        self._log_file = open(log_path, "ab")  # noqa: SIM115 -- closed in close()
        self.process = subprocess.Popen(
            command,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self._log_file,
            env=env,
            start_new_session=True,  # its own process group: a kill also ends whatever Blender started
        )
        self._replies: queue.Queue[str | None] = queue.Queue()
        self._reader = threading.Thread(target=self._read_replies, daemon=True)
        self._reader.start()
        self.ready = False
        self.info: dict[str, Any] = {}

    def _read_replies(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self._replies.put(line.decode("utf-8", errors="replace"))
        self._replies.put(None)  # end of file: the process is gone

    def log_size(self) -> int:
        try:
            return self.log_path.stat().st_size
        except OSError:
            return 0

    def log_since(self, offset: int) -> str:
        """Blender's log from byte ``offset`` on, at most its last :data:`LOG_TAIL_CHARS` characters."""
        try:
            with open(self.log_path, "rb") as log:
                log.seek(offset)
                text = log.read().decode("utf-8", errors="replace")
        except OSError:
            return ""
        return text[-LOG_TAIL_CHARS:]

    def _receive(self, deadline: float, what: str, log_offset: int) -> dict[str, Any]:
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                self.kill()
                raise _WorkerLost(f"timed out after {what}", self.log_since(log_offset))
            try:
                line = self._replies.get(timeout=remaining)
            except queue.Empty:
                continue
            if line is None:
                code = self.process.wait()
                self.kill()
                raise _WorkerLost(f"Blender worker exited ({_describe_exit(code)}) during {what}", self.log_since(log_offset))
            try:
                return json.loads(line)
            except json.JSONDecodeError:
                continue  # something else printed to the reply pipe: ignore it

    def wait_ready(self, timeout: float) -> None:
        if self.ready:
            return
        reply = self._receive(time.monotonic() + timeout, f"start-up ({timeout:g} s limit)", 0)
        if reply.get("event") != "ready":
            self.kill()
            raise _WorkerLost(f"unexpected first message from Blender worker: {reply}", self.log_since(0))
        self.ready = True
        self.info = reply

    def request(self, message: dict[str, Any], timeout: float) -> tuple[dict[str, Any], str]:
        """Send one request and wait for its reply; return the reply and the log written meanwhile."""
        offset = self.log_size()
        assert self.process.stdin is not None
        try:
            self.process.stdin.write((json.dumps(message) + "\n").encode())
            self.process.stdin.flush()
        except (BrokenPipeError, OSError):
            code = self.process.wait()
            self.kill()
            raise _WorkerLost(f"Blender worker exited ({_describe_exit(code)}) before the request", self.log_since(offset)) from None
        reply = self._receive(time.monotonic() + timeout, f"{timeout:g} s", offset)
        return reply, self.log_since(offset)

    def alive(self) -> bool:
        return self.process.poll() is None

    def kill(self) -> None:
        if self.process.poll() is None:
            try:
                os.killpg(self.process.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                self.process.kill()
            self.process.wait()
        self._close_files()

    def close(self, timeout: float = 10.0) -> None:
        """Ask the worker to quit; kill it if it does not within ``timeout`` seconds."""
        if self.process.poll() is None:
            try:
                assert self.process.stdin is not None
                self.process.stdin.write(b'{"op": "quit"}\n')
                self.process.stdin.flush()
                self.process.wait(timeout=timeout)
            except (BrokenPipeError, OSError, subprocess.TimeoutExpired):
                pass
        self.kill()

    def _close_files(self) -> None:
        for stream in (self.process.stdin, self.process.stdout):
            try:
                if stream is not None:
                    stream.close()
            except OSError:
                pass
        self._log_file.close()


def _describe_exit(code: int) -> str:
    if code < 0:
        try:
            return f"killed by signal {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


class BlenderWorkerPool:
    """Long-lived Blender worker processes that render one request after another.

    Parameters
    ----------
    workers : int
        Number of worker processes (one Cycles process already uses every core; more only help with several
        machines' worth of cores or a GPU per worker).
    max_renders_per_worker : int
        A worker is replaced after this many requests, to bound memory.
    timeout : float
        Seconds one request may take before its worker is killed.
    startup_timeout : float
        Seconds a new worker may take to import Blender.
    retries : int
        How many more times a request is tried, each on a fresh worker, after its worker crashed or timed out.
        Errors raised by Python code inside Blender are not retried.
    command : list of str, optional
        The worker command line (default: this interpreter running ``platesynth.render.blender.worker``).
    home : path-like, optional
        HOME / XDG directories of the workers (default :func:`blender_home`).

    Examples
    --------
    >>> with BlenderWorkerPool() as pool:                                    # doctest: +SKIP
    ...     reply = pool.request({"op": "ping"})
    """

    def __init__(
        self,
        workers: int = 1,
        *,
        max_renders_per_worker: int = 50,
        timeout: float = 300.0,
        startup_timeout: float = 120.0,
        retries: int = 1,
        command: list[str] | None = None,
        home: str | os.PathLike | None = None,
    ) -> None:
        if workers < 1 or max_renders_per_worker < 1 or timeout <= 0 or startup_timeout <= 0 or retries < 0:
            raise ValueError("workers and max_renders_per_worker must be >= 1, timeouts > 0, retries >= 0")
        self.max_renders_per_worker = max_renders_per_worker
        self.timeout = timeout
        self.startup_timeout = startup_timeout
        self.retries = retries
        self.command = list(command) if command else default_worker_command()
        self.home = Path(home) if home else blender_home()
        self.home.mkdir(parents=True, exist_ok=True)
        self.scratch = Path(tempfile.mkdtemp(prefix="platesynth-blender-"))
        self._slots: queue.Queue[_Worker | None] = queue.Queue()
        for _ in range(workers):
            self._slots.put(None)
        self._all: set[_Worker] = set()
        self._lock = threading.Lock()
        self._serial = itertools.count()
        self._closed = False
        self.workers_started = 0

    def __enter__(self) -> BlenderWorkerPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _start_worker(self) -> _Worker:
        with self._lock:
            if self._closed:
                raise RenderError("the Blender worker pool is closed")
            log_path = self.scratch / f"worker-{next(self._serial)}.log"
            worker = _Worker(self.command, worker_environment(self.home), log_path)
            self._all.add(worker)
            self.workers_started += 1
        return worker

    def _retire(self, worker: _Worker, *, kill: bool) -> None:
        worker.kill() if kill else worker.close()
        with self._lock:
            self._all.discard(worker)

    def new_output_dir(self) -> Path:
        """A fresh directory under the pool's scratch space for one request's files."""
        return Path(tempfile.mkdtemp(prefix="job-", dir=self.scratch))

    def request(self, message: dict[str, Any], *, timeout: float | None = None) -> dict[str, Any]:
        """Run one request on a worker; retry on a fresh worker after a crash or timeout.

        Parameters
        ----------
        message : dict
            JSON-serialisable request, e.g. ``{"op": "render", ...}`` (see :mod:`platesynth.render.blender.worker`).
        timeout : float, optional
            Seconds this request may take (default: the pool's ``timeout``).

        Returns
        -------
        dict
            The worker's reply (``ok`` is true), with ``log``: what Blender printed meanwhile.

        Raises
        ------
        BlenderScriptError
            Python code inside Blender raised (e.g. a bad parameter); the message names the error.
        BlenderWorkerError
            The worker crashed or timed out on every attempt; ``log`` holds the tail of Blender's log.
        """
        timeout = self.timeout if timeout is None else timeout
        attempts: list[str] = []
        last_log = ""
        for _attempt in range(1 + self.retries):
            worker = self._slots.get()
            try:
                if worker is None or not worker.alive():
                    if worker is not None:
                        self._retire(worker, kill=True)
                    worker = self._start_worker()
                worker.wait_ready(self.startup_timeout)
                reply, log = worker.request(message, timeout)
            except _WorkerLost as lost:
                attempts.append(lost.reason)
                last_log = lost.log
                if worker is not None:
                    self._retire(worker, kill=True)
                self._slots.put(None)
                continue
            except BaseException:
                if worker is not None:  # interrupted (e.g. Ctrl-C) while the worker was busy: it cannot be reused
                    self._retire(worker, kill=True)
                self._slots.put(None)
                raise
            worker.renders += 1
            if worker.renders >= self.max_renders_per_worker:
                self._retire(worker, kill=False)
                # start the replacement now: it imports Blender while the caller works on this result
                worker = None if self._closed else self._start_worker()
            self._slots.put(worker)
            if not reply.get("ok"):
                error = reply.get("error", "unknown error")
                raise BlenderScriptError(f"error inside Blender: {error}", log=(log + reply.get("traceback", ""))[-LOG_TAIL_CHARS:])
            reply["log"] = log
            return reply
        tries = "once" if len(attempts) == 1 else f"{len(attempts)} times"
        raise BlenderWorkerError(
            f"Blender failed {tries} on this request: {'; '.join(attempts)}", log=last_log, attempts=attempts
        )

    def close(self) -> None:
        """Stop every worker and remove the pool's scratch directory."""
        with self._lock:
            self._closed = True
            workers = list(self._all)
            self._all.clear()
        for worker in workers:
            worker.close(timeout=5.0)
        shutil.rmtree(self.scratch, ignore_errors=True)


_default_pool: BlenderWorkerPool | None = None
_default_pool_lock = threading.Lock()


def default_pool() -> BlenderWorkerPool:
    """The process-wide pool used by :func:`platesynth.render.blender.render_blender` (created on first use,
    closed at exit). Settings come from ``PLATESYNTH_BLENDER_WORKERS``, ``PLATESYNTH_BLENDER_MAX_RENDERS`` and
    ``PLATESYNTH_BLENDER_TIMEOUT`` where set."""
    global _default_pool
    with _default_pool_lock:
        if _default_pool is None or _default_pool._closed:
            _default_pool = BlenderWorkerPool(
                workers=int(setting_from_env("PLATESYNTH_BLENDER_WORKERS", 1)),
                max_renders_per_worker=int(setting_from_env("PLATESYNTH_BLENDER_MAX_RENDERS", 50)),
                timeout=setting_from_env("PLATESYNTH_BLENDER_TIMEOUT", 300.0),
            )
            atexit.register(_default_pool.close)
        return _default_pool


def setting_from_env(name: str, default: float) -> float:
    """A positive number from the environment variable ``name`` (``default`` where unset); integer where the
    default is.

    Raises
    ------
    ParameterError
        If the variable is set to something else.
    """
    text = os.environ.get(name)
    if text is None:
        return default
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if value <= 0 or (isinstance(default, int) and not value.is_integer()):
        raise ParameterError(f"${name} must be a positive {'integer' if isinstance(default, int) else 'number'}, got {text!r}")
    return value


def close_default_pool() -> None:
    """Stop the process-wide pool's workers now (a later render starts new ones)."""
    global _default_pool
    with _default_pool_lock:
        if _default_pool is not None:
            _default_pool.close()
            _default_pool = None
