"""Long work of the MCP server (render, train) as jobs: started at once, polled, waited for, cancelled.

A job runs its work in a thread of the server's process. The work reports progress through a callback after every
image or optimiser step; that callback is also where a job stops, by raising :class:`JobStopped`, when it is
cancelled or runs past its time limit. What a stopped job wrote stays resumable: a render's finished images, a
training's last finished epoch (its model directory says ``"complete": false``); starting the same job again goes
on from there.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, Field

from platesynth.agent.workspace import GuardrailError, Limits
from platesynth.schemas import OptimiseSummary, RenderSummary, TrainResult

logger = logging.getLogger(__name__)

State = Literal["running", "succeeded", "failed", "cancelled", "timed_out"]
Report = Callable[[int, int | None, str], None]
"""``report(done, total, message)``: the work's progress callback; raises :class:`JobStopped` to stop the work."""


class JobStopped(Exception):
    """Raised inside a job's work where it was cancelled or ran out of time."""


class JobStatus(BaseModel):
    """Where a job stands (the tools ``job_status``, ``job_wait``, ``job_cancel`` and ``jobs`` return it)."""

    job_id: str
    kind: str = Field(description="render, train or optimise")
    state: State = Field(description="running, then succeeded, failed, cancelled or timed_out")
    output: str = Field(description="the folder the job writes, relative to the workspace")
    done: int = Field(description="images rendered, optimiser steps taken or trials finished so far")
    total: int | None = Field(description="images, steps or trials in all (of the current stage)")
    message: str = Field(description="the latest progress message")
    seconds: float = Field(description="seconds since the job started (until it ended)")
    time_limit_seconds: float
    cancel_requested: bool = False
    arguments: dict[str, Any] = Field(description="the arguments the job was started with (its provenance)")
    result: RenderSummary | TrainResult | OptimiseSummary | None = Field(
        None, description="the job's result once it succeeded"
    )
    error: str | None = Field(None, description="one line, once it failed, was cancelled or timed out")


class JobList(BaseModel):
    """Every job of this server session, oldest first."""

    jobs: list[JobStatus]


@dataclass
class Job:
    """A job's state (see :class:`JobManager`)."""

    job_id: str
    kind: str
    output: Path
    output_name: str
    arguments: dict[str, Any]
    time_limit: float
    state: State = "running"
    done: int = 0
    total: int | None = None
    message: str = "starting"
    started: float = field(default_factory=time.monotonic)
    ended: float | None = None
    result: BaseModel | None = None
    error: str | None = None
    cancel: threading.Event = field(default_factory=threading.Event)
    finished: threading.Event = field(default_factory=threading.Event)

    def status(self) -> JobStatus:
        end = self.ended if self.ended is not None else time.monotonic()
        return JobStatus(
            job_id=self.job_id,
            kind=self.kind,
            state=self.state,
            output=self.output_name,
            done=self.done,
            total=self.total,
            message=self.message,
            seconds=round(end - self.started, 3),
            time_limit_seconds=self.time_limit,
            cancel_requested=self.cancel.is_set(),
            arguments=self.arguments,
            result=self.result,  # type: ignore[arg-type]
            error=self.error,
        )

    def report(self, done: int, total: int | None, message: str) -> None:
        """The work's progress callback: record, then stop if cancelled or out of time."""
        self.done, self.total, self.message = done, total, message
        if self.cancel.is_set():
            raise JobStopped("cancelled")
        if time.monotonic() - self.started > self.time_limit:
            raise JobStopped("timed_out")


def _overlap(a: Path, b: Path) -> bool:
    return a == b or a in b.parents or b in a.parents


class JobManager:
    """The jobs of one server: at most ``limits.max_jobs`` running at once, none writing where another writes."""

    def __init__(self, limits: Limits, describe_error: Callable[[BaseException], str], root: Path) -> None:
        self.limits = limits
        self.root = root
        self.describe_error = describe_error
        self._jobs: dict[str, Job] = {}
        self._lock = threading.Lock()

    def start(
        self,
        kind: str,
        output: Path,
        output_name: str,
        arguments: dict[str, Any],
        work: Callable[[Report], BaseModel],
        time_limit: float | None = None,
    ) -> JobStatus:
        """Start ``work(report)`` in a thread and return its status at once.

        Raises
        ------
        GuardrailError
            If ``limits.max_jobs`` jobs run already, or a running job writes into the same folder (or one inside
            or around it).
        """
        limit = self.limits.max_job_seconds if time_limit is None else min(time_limit, self.limits.max_job_seconds)
        with self._lock:
            running = [job for job in self._jobs.values() if job.state == "running"]
            if len(running) >= self.limits.max_jobs:
                raise GuardrailError(
                    f"{len(running)} job(s) running ({', '.join(j.job_id for j in running)}), the limit is "
                    f"{self.limits.max_jobs} (the server's --max-jobs); wait for one or cancel it"
                )
            for job in running:
                if _overlap(job.output, output):
                    raise GuardrailError(f"{output_name}: job {job.job_id} is writing there; wait for it or cancel it")
            job = Job(uuid.uuid4().hex[:12], kind, output, output_name, arguments, limit)
            self._jobs[job.job_id] = job
        thread = threading.Thread(target=self._run, args=(job, work), name=f"platesynth-job-{job.job_id}", daemon=True)
        thread.start()
        return job.status()

    def _run(self, job: Job, work: Callable[[Report], BaseModel]) -> None:
        try:
            result = work(job.report)
        except JobStopped as stop:
            job.state = "cancelled" if str(stop) == "cancelled" else "timed_out"
            job.error = (
                "cancelled by the client" if job.state == "cancelled"
                else f"stopped after its time limit of {job.time_limit:g} s (the server's --max-job-seconds)"
            )
            job.error += "; what it wrote is kept, and starting the same job again resumes it"
        except BaseException as exc:  # noqa: BLE001 -- any failure ends the job with one line
            job.state = "failed"
            job.error = " ".join(self.describe_error(exc).split()).replace(f"{self.root}/", "")
            logger.debug("job %s failed", job.job_id, exc_info=True)
        else:
            job.result = result
            job.state = "succeeded"
            job.message = "done"
        finally:
            job.ended = time.monotonic()
            job.finished.set()

    def get(self, job_id: str) -> Job:
        """The job ``job_id``.

        Raises
        ------
        GuardrailError
            For an unknown id.
        """
        with self._lock:
            job = self._jobs.get(job_id)
        if job is None:
            raise GuardrailError(f"no job {job_id!r} in this server session (the tool `jobs` lists them)")
        return job

    def all(self) -> list[Job]:
        """Every job, oldest first."""
        with self._lock:
            return list(self._jobs.values())

    def cancel(self, job_id: str) -> Job:
        """Ask the job to stop at its next progress point (images and steps are not cut half way)."""
        job = self.get(job_id)
        if job.state == "running":
            job.cancel.set()
        return job

    def shutdown(self, timeout: float = 10.0) -> None:
        """Cancel every running job and wait up to ``timeout`` seconds for them to stop."""
        jobs = self.all()
        for job in jobs:
            job.cancel.set()
        deadline = time.monotonic() + timeout
        for job in jobs:
            job.finished.wait(max(0.0, deadline - time.monotonic()))
