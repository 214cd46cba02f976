"""The job runner: a process pool behind a bounded, single-flight queue.

Every computation is a job keyed by its parameter hash.  ``submit`` returns the one
in-flight :class:`asyncio.Task` per key (identical concurrent requests share it), after
the job record is durably written; the task runs the kind's function in a worker
process, stores the JSON result, and finishes the record.  Numerics never run on the
event loop.

Limits: at most ``workers + queue_size`` distinct computations are in flight
(:class:`QueueFull` beyond, answered with 503).  Each computation has a runtime limit,
enforced cooperatively in the worker's progress callback and, for a worker that stops
reporting, by a watchdog that fails the job and replaces the pool's processes.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Any

from pydantic import BaseModel, ValidationError

from pipeflow.schema.registry import COMPUTATIONS
from service import observability, worker
from service.keys import Keyed
from service.settings import Settings
from service.store import Store

log = logging.getLogger("service.runner")

#: extra time past the runtime limit before the watchdog kills a worker [s]
WATCHDOG_GRACE_S = 5.0
#: attempts of one computation when worker processes die under it
MAX_ATTEMPTS = 3


class QueueFull(Exception):
    """No room for another computation."""


class ComputationFailed(Exception):
    """The computation ended in a failure; ``problem`` is its RFC 9457 document."""

    def __init__(self, problem: dict[str, Any]) -> None:
        super().__init__(problem.get("detail", "failed"))
        self.problem = problem


class ComputationCancelled(Exception):
    """The computation was cancelled (DELETE on its job)."""


@dataclass
class Flight:
    job: Keyed
    task: asyncio.Task[bytes]
    accepted: asyncio.Event = field(default_factory=asyncio.Event)
    killed: bool = False
    #: a DELETE asked this run to stop: a resubmission waits for it and starts a new run
    cancelled: bool = False

    @property
    def key(self) -> str:
        return self.job.key


class Runner:
    def __init__(self, settings: Settings, store: Store) -> None:
        self.settings = settings
        self.store = store
        self.capacity = settings.workers + settings.queue_size
        self.computations = 0  # runs handed to the pool (tests check single-flight with it)
        self.ready = False
        self.watchdog_grace_s = WATCHDOG_GRACE_S
        self._flights: dict[str, Flight] = {}
        self._pool: ProcessPoolExecutor | None = None
        self._background: set[asyncio.Task[Any]] = set()

    # -- lifecycle -----------------------------------------------------------------------

    async def start(self) -> None:
        """Start the pool, re-enqueue jobs a previous process left active, start the watchdog."""
        self._pool = self._new_pool()
        pruned = await asyncio.to_thread(
            self.store.prune_jobs, time.time() - self.settings.job_retention_s
        )
        if pruned:
            log.info("pruned %d old job records", pruned)
        for job in await asyncio.to_thread(self.store.active_jobs):
            computation = COMPUTATIONS.get(job.kind)
            try:
                if computation is None:
                    raise LookupError(f"unknown job kind {job.kind!r} after restart")
                # a stored request is validated like a new one (once, for this run)
                request: BaseModel = computation.request.model_validate(job.spec)
            except (LookupError, ValidationError) as exc:
                await asyncio.to_thread(
                    self.store.finish_job, job.key, "failed", {"detail": str(exc)}
                )
                continue
            log.info("re-enqueuing %s job %s left %s", job.kind, job.key, job.status)
            await self.submit(Keyed(computation, request, job.spec, job.key), recover=True)
        self._spawn(self._warm_up())
        self._spawn(self._watchdog())

    async def stop(self) -> None:
        for task in list(self._background):
            task.cancel()
        for flight in list(self._flights.values()):
            flight.task.cancel()  # records stay active: the next start re-enqueues them
        if self._pool is not None:
            self._kill(self._pool)
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
        self.ready = False

    def _new_pool(self) -> ProcessPoolExecutor:
        # spawn: fresh interpreters, so init() pins BLAS threads before numpy loads
        return ProcessPoolExecutor(
            max_workers=self.settings.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=worker.init,
            initargs=(self.settings.log_level, self.settings.log_format),
        )

    @staticmethod
    def _kill(pool: ProcessPoolExecutor) -> None:
        # the executor has no public per-process kill before Python 3.14
        for proc in list(getattr(pool, "_processes", {}).values()):
            with contextlib.suppress(Exception):
                proc.kill()

    def _spawn(self, coro: Any) -> None:
        task = asyncio.create_task(coro)
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    async def _warm_up(self) -> None:
        """Start every worker (imports included) before declaring the service ready."""
        loop = asyncio.get_running_loop()
        while True:
            pool = self._pool
            assert pool is not None
            try:
                await asyncio.gather(
                    *(loop.run_in_executor(pool, worker.ping) for _ in range(self.settings.workers))
                )
            except BrokenProcessPool:
                log.exception("worker processes failed to start; retrying")
                self._replace_pool(pool)
                await asyncio.sleep(1.0)
                continue
            self.ready = True
            return

    async def call(self, fn: Any, *args: Any) -> Any:
        """Run a picklable function in a worker (tests and diagnostics)."""
        assert self._pool is not None
        return await asyncio.get_running_loop().run_in_executor(self._pool, fn, *args)

    # -- state ---------------------------------------------------------------------------

    @property
    def in_flight(self) -> int:
        return len(self._flights)

    @property
    def saturated(self) -> bool:
        return len(self._flights) >= self.capacity

    def is_active(self, key: str) -> bool:
        return key in self._flights

    # -- submission ----------------------------------------------------------------------

    async def submit(
        self, job: Keyed, *, force: bool = False, recover: bool = False
    ) -> asyncio.Task[bytes]:
        """The in-flight task for ``job.key``, started if needed, once its record is written.

        ``force`` recomputes even if a result is stored; ``recover`` bypasses the queue
        bound (for jobs accepted before a restart).  A run that a DELETE asked to stop is
        never shared: the resubmission waits until it has stopped (its worker checks the
        flag at its next progress report), then starts a new run.
        """
        key = job.key
        while (old := self._flights.get(key)) is not None and old.cancelled:
            with contextlib.suppress(Exception, asyncio.CancelledError):
                await asyncio.shield(old.task)
            if self._flights.get(key) is old:  # its done-callback has not run yet
                del self._flights[key]
        flight = self._flights.get(key)
        if flight is None:
            if not recover and self.saturated:
                raise QueueFull(f"{self.in_flight} computations in flight")
            accepted = asyncio.Event()
            task = asyncio.create_task(self._run(job, force, accepted))
            flight = Flight(job, task, accepted)
            self._flights[key] = flight
            task.add_done_callback(functools.partial(self._done, flight))
        await flight.accepted.wait()
        return flight.task

    def cancel(self, key: str) -> None:
        """Mark the run of ``key`` (if any) as asked to stop; see :meth:`submit`.  The job
        record's cancel flag, which the worker reads, is set by the caller."""
        flight = self._flights.get(key)
        if flight is not None:
            flight.cancelled = True

    def _done(self, flight: Flight, task: asyncio.Task[bytes]) -> None:
        if self._flights.get(flight.key) is flight:
            del self._flights[flight.key]
        if not task.cancelled():
            task.exception()  # retrieved here so an unobserved job failure is not logged twice

    async def _run(self, job: Keyed, force: bool, accepted: asyncio.Event) -> bytes:
        key, name = job.key, job.computation.name
        try:
            await asyncio.to_thread(self.store.enqueue_job, key, name, job.canonical)
        finally:
            accepted.set()
        if not force:
            body = await asyncio.to_thread(self.store.get_result, key)
            if body is not None:  # computed between the caller's cache check and now
                await asyncio.to_thread(self.store.finish_job, key, "succeeded")
                return body
        started = time.perf_counter()
        status, payload = await self._execute(job)
        observability.record_computation(
            name,
            "error" if status == "error" else status,
            time.perf_counter() - started,
            payload if status == "ok" else None,
        )
        if status == "ok":
            await asyncio.to_thread(self.store.put_result, key, name, payload)
            await asyncio.to_thread(self.store.finish_job, key, "succeeded")
            return bytes(payload)
        if status == "cancelled":
            await asyncio.to_thread(
                self.store.finish_job, key, "cancelled", {"detail": str(payload)}
            )
            raise ComputationCancelled(str(payload))
        await asyncio.to_thread(self.store.finish_job, key, "failed", payload)
        raise ComputationFailed(payload)

    async def _execute(self, job: Keyed) -> worker.Outcome:
        key = job.key
        loop = asyncio.get_running_loop()
        for attempt in range(1, MAX_ATTEMPTS + 1):
            pool = self._pool
            assert pool is not None
            self.computations += 1
            try:
                return await loop.run_in_executor(
                    pool,
                    worker.run,
                    job.computation,
                    job.request,
                    key,
                    str(self.store.path),
                    self.settings.job_timeout_s,
                    self.settings.progress_interval_s,
                    observability.request_id(),
                )
            except BrokenProcessPool:
                flight = self._flights.get(key)
                if flight is not None and flight.killed:
                    return ("error", worker.runtime_problem(self.settings.job_timeout_s))
                log.warning("worker died under job %s (attempt %d)", key, attempt)
                self._replace_pool(pool)
        return (
            "error",
            {
                "type": "about:blank",
                "title": "Internal server error",
                "status": 500,
                "detail": f"worker processes died {MAX_ATTEMPTS} times running this job",
            },
        )

    def _replace_pool(self, broken: ProcessPoolExecutor) -> None:
        if self._pool is broken:
            self._kill(broken)
            broken.shutdown(wait=False)
            self._pool = self._new_pool()

    async def _watchdog(self) -> None:
        """Fail computations that overrun the runtime limit without reporting progress."""
        timeout = self.settings.job_timeout_s
        while True:
            limit = timeout + max(self.watchdog_grace_s, 0.1 * timeout)
            await asyncio.sleep(1.0)
            if not self._flights:
                continue
            now = time.time()
            jobs = await asyncio.to_thread(self.store.active_jobs)
            overdue = [
                j.key
                for j in jobs
                if j.status == "running"
                and j.started
                and now - j.started > limit
                and j.key in self._flights
            ]
            for key in overdue:
                log.warning("job %s overran the runtime limit: replacing the worker pool", key)
                self._flights[key].killed = True
            if overdue and self._pool is not None:
                self._replace_pool(self._pool)
