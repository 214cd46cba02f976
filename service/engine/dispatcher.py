"""The durable queue's dispatcher: asynchronous jobs wait as store records that nobody
drives yet (:meth:`Store.queue_job`); this replica takes the next ones
(:meth:`Store.claim_waiting`: in order, fairly between clients, never one job by two
replicas) whenever it has fewer computations in flight than workers, and hands each to
``drive(job)`` (the runner drives it as a recovered record).  A queued job survives any
restart: it is a row.

It is woken (:meth:`Dispatcher.kick`) by a job queued here and by a flight that ends, and
polls every ``poll_s`` otherwise (jobs queued by other replicas).  It knows nothing of
flights or workers: ``free_slots()`` is a callback of the runner.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
from collections.abc import Awaitable, Callable

from service.engine.outcome import QueueFull
from service.keys import Keyed
from service.settings import Settings
from service.store import Job, StorageError, Store

log = logging.getLogger("service.engine")


class Dispatcher:
    """Takes waiting jobs from the durable queue as slots free up; ``dispatched`` counts
    the jobs this replica took (tests)."""

    def __init__(
        self,
        settings: Settings,
        store: Store,
        replica: str,
        *,
        connected: asyncio.Event,
        free_slots: Callable[[], int],
        drive: Callable[[Job], Awaitable[None]],
        poll_s: float,
    ) -> None:
        self.settings = settings
        self.store = store
        self.replica = replica
        self._connected = connected
        self._free_slots = free_slots
        self._drive = drive
        self.poll_s = poll_s
        self._kick = asyncio.Event()
        #: the last look found no job it could take waiting (it had slots to spare): a
        #: flight that ends does not wake it (see :meth:`slot_freed`)
        self.drained = False
        self._round = asyncio.Lock()
        self.dispatched = 0

    def kick(self) -> None:
        """Look at the queue now (a job was queued or put back)."""
        self._kick.set()

    def slot_freed(self) -> None:
        """A flight ended: look at the queue, unless its last look found it drained."""
        if not self.drained:
            self._kick.set()

    async def enqueue(
        self, job: Keyed, *, force: bool = False, principal: str | None = None, cost: float = 0.0
    ) -> Job:
        """Accept ``job`` into the store's durable queue (or join its active record) and
        take what a free worker can take; its record.  Raises :class:`QueueFull` when
        ``max_queued_jobs`` jobs wait already, :class:`StorageError` when the store fails."""
        if not self.store.healthy:
            raise self.store.unavailable()
        bound = self.settings.max_queued_jobs
        record, accepted = await asyncio.to_thread(
            functools.partial(
                self.store.queue_job,
                job.key,
                job.computation.name,
                job.canonical,
                bound=bound,
                refresh=force,
                principal=principal,
                cost=cost,
            )
        )
        if not accepted or record is None:
            raise QueueFull(f"{bound} jobs wait in the queue")
        # a free worker takes the next job before the 202 is answered (not at the
        # dispatcher's next wake-up): a request right after it finds the slot taken; the
        # job is accepted whatever happens here (the dispatcher tries again)
        try:
            await self.once()
        except StorageError:
            self._kick.set()
        return record

    async def run(self) -> None:
        """Take waiting jobs as workers free up, until cancelled."""
        await self._connected.wait()
        while True:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._kick.wait(), self.poll_s)
            self._kick.clear()
            try:
                await self.once()
            except StorageError:
                continue
            except Exception:
                log.exception("engine dispatcher")

    async def once(self) -> None:
        """Take as many waiting jobs as there are free slots and drive them (one round at
        a time: two rounds would both count the same free slots)."""
        async with self._round:
            free = self._free_slots()
            self.drained = False  # unknown until the read below says otherwise
            if free <= 0 or not self.store.healthy or not self._connected.is_set():
                return
            per_principal = self.settings.quota_concurrent_jobs
            taken = await asyncio.to_thread(
                self.store.claim_waiting, self.replica, free, per_principal
            )
            # fewer than it could take, and no client's quota held one back: nothing
            # waited beyond these.  A flight that ends then leaves the dispatcher asleep
            # (its read after every computation, each cold request's, was a thread hop
            # and a query); a job queued later wakes it (enqueue), or, from another
            # replica, its next poll (poll_s) takes it
            self.drained = len(taken) < free and per_principal is None
            for job in taken:
                self.dispatched += 1
                await self._drive(job)
        if len(taken) == free:
            self._kick.set()  # there may be more, and room once these end
