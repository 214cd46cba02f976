"""Driving one flight's job to a terminal record: write it (or let the fast lane write it),
submit its task, follow the record until it ends, and answer with the body or the error.

The task owns the record while it runs (a lease in the store), so this loop mostly waits:
for its task's :class:`~service.engine.outcome.Outcome`, for the monitor to flag a change,
or a poll interval.  What it does next is a ``match`` over the state it reads
(:meth:`Driver._next`): the task's :class:`TaskStatus` first, then the record's lease.

It knows nothing of the lane, the cluster or the long polls: it is handed ``first(flight,
force)`` (the first step of a new job: the lane, or a lookup), ``submit(flight, job)`` (one
attempt of the task), ``ended(key)`` (the record is final: wake the long polls),
``handed_off(key, note)`` (the lane's allowance stopped a run) and ``fail_later(key, doc)``
(a failure to write once the store takes writes again).
"""

from __future__ import annotations

import asyncio
import functools
import logging
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from enum import Enum, auto
from typing import Any

from pipeflow.errors import ErrorRecord
from service import observability
from service.engine import flight as flights
from service.engine.flight import Flight
from service.engine.lifecycle import Counted, JobState, TaskStatus
from service.engine.outcome import (
    ComputationCancelled,
    ComputationFailed,
    Outcome,
    internal,
    raise_unless_succeeded,
    result_of,
)
from service.keys import Keyed
from service.settings import Settings
from service.store import Job, StorageError, Store

log = logging.getLogger("service.engine")

#: starts of one computation (worker deaths under it) before its job is failed
MAX_ATTEMPTS = 3

First = Callable[[Flight, bool], Awaitable[tuple[Job | None, "asyncio.Future[Outcome] | None"]]]


class Step(Enum):
    """What the driving loop does next with an active record (:meth:`Driver._next`)."""

    WAIT = auto()  # until the task ends, the monitor flags a change, or a poll interval
    RETRY = auto()  # the task itself failed to run: again, under a fresh Dask key
    GIVE_UP = auto()  # its worker died MAX_ATTEMPTS times: fail the job
    SUBMIT = auto()  # nobody computes it: start an attempt


@dataclass
class _Run:
    """The driving loop's state: the running attempt's outcome to come (``waiter``), the
    record as a write left it (``known``: not read again) and the (generation, attempts)
    of the last attempt submitted (``tag``)."""

    waiter: asyncio.Future[Outcome] | None = None
    known: Job | None = None
    tag: tuple[int, int] | None = None


class Driver:
    """Drives flights (see the module docstring); ``poll_s`` [s] is the pause before a
    task that failed to run is submitted again."""

    def __init__(
        self,
        settings: Settings,
        store: Store,
        replica: str,
        *,
        connected: asyncio.Event,
        first: First,
        submit: Callable[[Flight, Job], Awaitable[Outcome]],
        ended: Callable[[str], None],
        handed_off: Callable[[str, str | None], None],
        fail_later: Callable[[str, dict[str, Any]], None],
        poll_s: float,
    ) -> None:
        self.settings = settings
        self.store = store
        self.replica = replica
        self._connected = connected
        self._first = first
        self._submit = submit
        self._ended = ended
        self._handed_off = handed_off
        self._fail_later = fail_later
        self.poll_s = poll_s

    async def drive(self, flight: Flight, force: bool, recover: bool) -> bytes:
        """The body of ``flight``'s job, counted in the computation metrics."""
        started = time.perf_counter()
        try:
            body = await self._drive(flight, force, recover)
        except ComputationCancelled:
            self._record(flight, Counted.CANCELLED, started, None)
            raise
        except ComputationFailed:
            self._record(flight, Counted.ERROR, started, None)
            raise
        self._record(flight, Counted.OK, started, body)
        return body

    def _record(self, flight: Flight, outcome: Counted, started: float, body: bytes | None) -> None:
        """Count a computation this flight saw finish (not a result found stored)."""
        if flight.seconds is None and outcome != Counted.CANCELLED:
            return
        seconds = flight.seconds if flight.seconds is not None else time.perf_counter() - started
        observability.record_computation(flight.job.computation.name, outcome, seconds, body)

    async def _drive(self, flight: Flight, force: bool, recover: bool) -> bytes:
        run = await self._accept(flight, force, recover)
        if run.waiter is not None:  # computing in the lane already: its end is the next news
            await self._wait(flight, run.waiter)
        await self._connected.wait()
        while True:
            if flight.cancelled:
                await self._stopped(flight, run.waiter)
            settled = await self._settled(flight, run)
            if isinstance(settled, bytes):
                return settled
            if settled:
                continue  # the record written again from the stored result: from the top
            job = await self._read(flight.key, run)
            if job is None:
                continue  # the store failed the read: tried again after a pause
            if not job.active:
                return await self._ended_with(flight, run, job)
            match await self._next(flight, run, job):
                case Step.WAIT:
                    await self._wait(flight, run.waiter)
                case Step.RETRY:
                    await asyncio.sleep(self.poll_s)
                case Step.GIVE_UP:
                    await self._give_up(flight.key, job)
                case Step.SUBMIT:
                    run.tag = (job.generation, job.attempts)
                    run.waiter = asyncio.ensure_future(result_of(self._submit(flight, job)))
                    # the record is read again once the task ends or the monitor flags a
                    # change, not right away (that read only competed with the task starting)
                    await self._wait(flight, run.waiter)

    async def _accept(self, flight: Flight, force: bool, recover: bool) -> _Run:
        """The flight's first step: a new job's record written (by the lane's run, or
        queued here); a recovered one is active already.  ``accepted`` is set after it,
        whatever happens."""
        run = _Run()
        try:
            if not recover:
                run.known, run.waiter = await self._first(flight, force)
                if run.known is None and run.waiter is None:
                    run.known = await self._enqueue(flight, refresh=force)
        finally:
            flight.accepted.set()
        return run

    async def _settled(self, flight: Flight, run: _Run) -> bytes | bool:
        """The body, if the attempt's outcome answers the request without reading the
        record: a lookup that found the result stored, or a task that stored the result
        and finished the record with it (the fast lane's answer even carries the body).
        True: a stored result found while another request joined, the record written
        again from it (``run.known``) for the ordinary path to finish; False: go on."""
        if run.waiter is None or not run.waiter.done():
            return False
        outcome = run.waiter.result()
        match outcome.status:
            case TaskStatus.HIT:
                # the lookup wrote nothing; a request that joined meanwhile writes a record
                # (its own lookup missed: an eviction in between), which the ordinary path
                # finishes from the stored result (written here too, as the joiner does:
                # either write may come first)
                run.waiter = None
                assert outcome.body is not None
                if not flight.joined:
                    flight.hit = True
                    return outcome.body
                run.known = await self._enqueue(flight, keep_stored=True)
                return True
            case _ if outcome.finished:  # (succeeded: only a run that stored it finishes)
                flight.seconds = outcome.seconds
                self._ended(flight.key)  # the record is final: long polls answer now
                return outcome.body if outcome.body is not None else await self._body(flight.key)
        return False

    async def _read(self, key: str, run: _Run) -> Job | None:
        """The record (as the last write left it, else read); None after a pause when the
        store failed the read.  Raises :class:`ComputationFailed` when it is gone."""
        job, run.known = run.known, None
        if job is None:
            try:
                job = await asyncio.to_thread(self.store.get_job, key)
            except StorageError:
                await asyncio.sleep(self.settings.retry_after_s)
                return None
            if job is None:
                raise ComputationFailed(internal(f"the record of job {key} disappeared"))
        return job

    async def _ended_with(self, flight: Flight, run: _Run, job: Job) -> bytes:
        """The answer of the ended record ``job``."""
        if run.waiter is not None and job.started is not None and job.finished is not None:
            # our task finished it (its own answer may still be on the way)
            flight.seconds = job.finished - job.started
        raise_unless_succeeded(job)
        return await self._body(job.key)

    async def _next(self, flight: Flight, run: _Run, job: Job) -> Step:
        """What to do with the active record ``job``: the attempt's outcome first (if it
        ended), then the record's lease."""
        if run.waiter is not None:
            if not run.waiter.done():
                return Step.WAIT
            outcome, run.waiter = run.waiter.result(), None
            if outcome.seconds is not None:
                flight.seconds = outcome.seconds
            match outcome.status:
                case TaskStatus.HANDOFF:
                    # the lane's allowance stopped it: the record is unowned and says why,
                    # and the submission below goes to a worker (no first attempt now)
                    self._handed_off(flight.key, outcome.note)
                case TaskStatus.STORAGE:
                    assert outcome.error is not None
                    await self._storage_failure(flight.key, outcome.error)
                case TaskStatus.EXCEPTION:
                    log.warning("task of job %s ended abnormally: %s", flight.key, outcome.note)
                    flight.resubmits += 1  # a fresh Dask key: the old one may be erred
                    run.tag = None
                    return Step.RETRY
        return self._lease(job, run.tag)

    def _lease(self, job: Job, tag: tuple[int, int] | None) -> Step:
        """What the active record's lease says: a live attempt holds it (wait); its
        holder died too often (give up); our task ran and left it queued (wait); or
        nobody computes it (submit)."""
        stale = job.heartbeat is None or time.time() - job.heartbeat >= self.settings.stale_after_s
        if job.owner is not None and not stale:
            return Step.WAIT
        if job.owner is not None and job.attempts >= MAX_ATTEMPTS:
            return Step.GIVE_UP
        if tag == (job.generation, job.attempts) and job.owner is None and not stale:
            return Step.WAIT
        return Step.SUBMIT

    async def _give_up(self, key: str, job: Job) -> None:
        message = (
            f"the computation started {job.attempts} times and its worker died each "
            f"time (last: attempt {job.attempts} on {job.worker} stopped heartbeating)"
        )
        await asyncio.to_thread(self.store.finish_job, key, JobState.FAILED, internal(message))

    async def _wait(self, flight: Flight, waiter: asyncio.Future[Any] | None) -> None:
        """Until ``waiter`` is done, the monitor flags a change, or one poll interval."""
        await flights.wait(flight, waiter, self.settings.stale_after_s / 4)

    async def _stopped(self, flight: Flight, waiter: asyncio.Future[Any] | None) -> None:
        """A DELETE asked this run to stop: wait until its task has stopped (or never
        took the lease), reading the record through the monitor's query only."""
        while waiter is not None and not waiter.done():
            records = await asyncio.to_thread(self.store.jobs_by_key, [flight.key])
            record = records.get(flight.key)
            if record is None or record.owner is None:
                break  # not computing: the task finds the record cancelled when it starts
            await self._wait(flight, waiter)
        raise ComputationCancelled("cancelled by request")

    async def join(
        self, flight: Flight, job: Keyed, force: bool, principal: str | None, cost: float
    ) -> None:
        """Another request for the job of ``flight``: its record is accepted again (a
        finished one gets a new generation), but for a run that has just stored its result
        (a request that missed the store a moment before it was written: the flight
        answers it; resetting would compute twice); the flight is told."""
        flight.joined = True
        await asyncio.to_thread(
            functools.partial(
                self.store.enqueue_job,
                flight.key,
                job.computation.name,
                job.canonical,
                refresh=force,
                keep_stored=not force,
                principal=principal,
                cost=cost,
                dispatcher=self.replica,
            )
        )
        flight.changed.set()

    async def _enqueue(self, flight: Flight, **how: bool) -> Job:
        """The flight's job record written (``Store.enqueue_job``, off the event loop):
        queued, or answered from a stored result; ``how``: ``refresh`` / ``keep_stored``."""
        job_in = flight.job
        return await asyncio.to_thread(
            functools.partial(
                self.store.enqueue_job,
                flight.key,
                job_in.computation.name,
                job_in.canonical,
                principal=flight.principal,
                cost=flight.cost,
                dispatcher=self.replica,
                **how,
            )
        )

    async def _storage_failure(self, key: str, failure: ErrorRecord) -> None:
        """The task could not store its result: fail the job with the reason (if the store
        takes that write) and answer the waiting request with the storage error."""
        message, full = failure.message, bool(failure.data.get("full"))
        doc = ErrorRecord(
            "storage",
            "storage",
            f"the result could not be stored: {message}",
            data={"full": full},
        ).to_dict()
        self.store.mark_failed(message, full=full)  # not ready until a probe write succeeds
        try:
            await asyncio.to_thread(self.store.finish_job, key, JobState.FAILED, doc)
        except StorageError:
            self._fail_later(key, doc)  # written by the monitor once writes work
        raise StorageError(message, full=full)

    async def _body(self, key: str) -> bytes:
        """The stored result of a succeeded job, sent once to the requests waiting for it,
        not kept in the store's memory front: a 60 s mixed load filled that to its 64 MB
        bound with fresh results."""
        body = await asyncio.to_thread(
            functools.partial(self.store.get_result, key, remember=False)
        )
        if body is None:
            raise ComputationFailed(internal(f"the result of job {key} was evicted"))
        return body
