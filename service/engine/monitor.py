"""The monitor: one loop per replica, every ``poll_s``, that

- probes a failed store until it is writable again, then writes the failures it could not
  write then (:meth:`Monitor.fail_later`);
- wakes the flights whose record ended, or whose lease went stale, and the long polls of
  jobs no flight here drives (``ended(key)``);
- keeps the heartbeat of the queued jobs this replica waits for;
- puts back in the queue the jobs a dead replica took but never started (``requeued()``),
  and recovers any job whose heartbeat went stale (its worker, its replica or the
  scheduler died) with ``recover(job)``: nothing accepted is lost.

It also ends at once the leases of the jobs a lost worker ran (:meth:`Monitor.worker_lost`,
the cluster's event).  It reads the flights (:class:`~service.engine.flight.Flights`, the
floor below it) and calls back the runner for the rest.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Awaitable, Callable
from typing import Any

from service.engine.flight import Flights
from service.engine.lifecycle import JobState
from service.settings import Settings
from service.store import Job, StorageError, Store

log = logging.getLogger("service.engine")


class Monitor:
    """See the module docstring; ``watched()`` gives the keys long-polled here."""

    def __init__(
        self,
        settings: Settings,
        store: Store,
        flights: Flights,
        *,
        watched: Callable[[], list[str]],
        ended: Callable[[str], None],
        requeued: Callable[[], None],
        recover: Callable[[Job], Awaitable[None]],
        poll_s: float,
    ) -> None:
        self.settings = settings
        self.store = store
        self.flights = flights
        self._watched = watched
        self._ended = ended
        self._requeued = requeued
        self._recover = recover
        self.poll_s = poll_s
        # jobs to fail with their storage error once the store takes writes again
        self.pending_failures: dict[str, dict[str, Any]] = {}
        self._last_touch = self._last_recovery = 0.0

    def fail_later(self, key: str, doc: dict[str, Any]) -> None:
        """Fail the job ``key`` with the error ``doc`` once the store takes writes again."""
        self.pending_failures[key] = doc

    async def run(self) -> None:
        """Every ``poll_s``, :meth:`once`, until cancelled."""
        while True:
            await asyncio.sleep(self.poll_s)
            try:
                await self.once()
            except StorageError:
                continue
            except Exception:
                log.exception("engine monitor")

    async def once(self) -> None:
        """One look (see the module docstring)."""
        if not self.store.healthy:
            await asyncio.to_thread(self.store.probe)
            return
        while self.pending_failures:
            key, doc = next(iter(self.pending_failures.items()))
            await asyncio.to_thread(self.store.finish_job, key, JobState.FAILED, doc)
            del self.pending_failures[key]
        now = time.time()
        records = await self._wake(now)
        stale_after = self.settings.stale_after_s
        if now - self._last_touch >= stale_after / 3:
            self._last_touch = now
            queued = [k for k, j in records.items() if j.status == JobState.QUEUED]
            await asyncio.to_thread(self.store.touch, queued)
        if now - self._last_recovery >= stale_after / 2:
            self._last_recovery = now
            if await asyncio.to_thread(self.store.requeue_stale, stale_after):
                self._requeued()  # back in the queue: taken as slots free up
            for job in await asyncio.to_thread(self.store.stale_jobs, stale_after):
                if job.key not in self.flights:
                    await self._recover(job)

    async def _wake(self, now: float) -> dict[str, Job]:
        """Read the records of the flights and of the long-polled jobs no flight here
        drives (queued, or run by another replica) in one query; wake those whose record
        ended (or whose lease is dead); the flights' records."""
        keys = list(self.flights)
        watched = [k for k in self._watched() if k not in self.flights]
        records = await asyncio.to_thread(self.store.jobs_by_key, keys + watched)
        for key in watched:
            job = records.pop(key, None)
            if job is None or not job.active:
                self._ended(key)
        stale_after = self.settings.stale_after_s
        for key in keys:
            job = records.get(key)
            lease_dead = (
                job is not None
                and job.owner is not None
                and (job.heartbeat is None or now - job.heartbeat >= stale_after)
            )
            if job is None or not job.active or lease_dead:
                self.flights.wake(key)
        return records

    async def release_finished(self, wait_s: float = 1.0) -> None:
        """Free the slots of flights whose job record has already ended (e.g. failed by a
        worker's watchdog) without waiting for the next look: wake them and give them up
        to ``wait_s`` [s] to leave.  A store that cannot be read frees nothing."""
        keys = list(self.flights)
        try:
            records = await asyncio.to_thread(self.store.jobs_by_key, keys)
        except StorageError:
            return
        ended = []
        for key in keys:
            job, flight = records.get(key), self.flights.get(key)
            if flight is not None and flight.task is not None and job is not None:
                if not job.active:
                    flight.changed.set()
                    ended.append(flight.task)
        if ended:
            await asyncio.wait(ended, timeout=wait_s)

    async def worker_lost(self, address: str) -> None:
        """Dask's worker-loss signal: the leases of the jobs that worker was running end
        now (their computation is taken over at once, by Dask's rescheduled task or a
        replica's recovery) instead of after ``stale_after_s`` without heartbeat."""
        try:
            keys = await asyncio.to_thread(
                self.store.expire_leases, address, time.time() - self.settings.stale_after_s
            )
        except StorageError:
            return  # the stale timeout recovers them
        if keys:
            log.warning("worker %s left: %d job lease(s) ended", address, len(keys))
            for key in keys:
                self.flights.wake(key)
