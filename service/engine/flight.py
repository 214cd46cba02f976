"""Single flight, on the floor of the engine: at most one :class:`Flight` per job key in this
replica, the one :class:`asyncio.Task` that drives the job to a terminal record, which every
request for that key shares (:class:`Flights`, the table the runner's parts read).

A flight is told of changes by its ``changed`` event (set by the monitor, a DELETE, a lost
worker); :func:`wait` is how a driving loop sleeps until then.  Imports nothing of the
engine's upper parts (the runner hands them this table).
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable, Coroutine, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from service.engine.lifecycle import TaskStatus
from service.engine.outcome import Outcome

if TYPE_CHECKING:
    from service.keys import Keyed
    from service.store import Store


@dataclass
class Flight:
    job: Keyed
    task: asyncio.Task[bytes] | None = None
    accepted: asyncio.Event = field(default_factory=asyncio.Event)
    changed: asyncio.Event = field(default_factory=asyncio.Event)
    resubmits: int = 0
    #: a DELETE asked this run to stop: a resubmission waits for it and starts a new run
    cancelled: bool = False
    #: how long the last finished attempt computed [s] (for the computation metrics)
    seconds: float | None = None
    #: who asked, and the estimated cost: written on the record this flight creates
    principal: str | None = None
    cost: float = 0.0
    #: the request's cache lookup is this flight's first step (:meth:`Runner.look_up_or_run`)
    look_up: bool = False
    #: ... and it found the result stored: the body is a hit, no record was written
    hit: bool = False
    #: another request joined this flight (its record may have been written by it)
    joined: bool = False

    @property
    def key(self) -> str:
        return self.job.key


class Flights:
    """The flights of this replica by job key, at most ``capacity`` at once (beyond it a
    new flight is refused, :class:`~service.engine.outcome.QueueFull`, unless it recovers
    an active record).  ``ended(flight, freed)`` is called when a flight's task ends
    (``freed``: it left the table now, a slot is free)."""

    def __init__(self, capacity: int, ended: Callable[[Flight, bool], None]) -> None:
        self.capacity = capacity
        self._ended = ended
        self._by_key: dict[str, Flight] = {}

    def __len__(self) -> int:
        return len(self._by_key)

    def __contains__(self, key: object) -> bool:
        return key in self._by_key

    def __iter__(self) -> Iterator[str]:
        return iter(list(self._by_key))

    def get(self, key: str) -> Flight | None:
        return self._by_key.get(key)

    @property
    def table(self) -> dict[str, Flight]:
        """The flights by key (read only: the runner's ``_flights``, for tests)."""
        return self._by_key

    @property
    def saturated(self) -> bool:
        return len(self._by_key) >= self.capacity

    def start(
        self, flight: Flight, drive: Callable[[Flight], Coroutine[Any, Any, bytes]]
    ) -> Flight:
        """Enter ``flight`` and start its task, ``drive(flight)``."""
        self._by_key[flight.key] = flight
        flight.task = asyncio.create_task(drive(flight))
        flight.task.add_done_callback(lambda task: self._done(flight, task))
        return flight

    def _done(self, flight: Flight, task: asyncio.Task[bytes]) -> None:
        freed = self._by_key.get(flight.key) is flight
        if freed:
            del self._by_key[flight.key]
        self._ended(flight, freed)
        if not task.cancelled():
            task.exception()  # retrieved here so an unobserved job failure is not logged twice

    async def cancelled_gone(self, key: str) -> None:
        """Wait until no run of ``key`` that a DELETE asked to stop is left here (it is
        never shared: a new request starts a new run once it has stopped)."""
        while (old := self._by_key.get(key)) is not None and old.cancelled:
            assert old.task is not None
            with contextlib.suppress(Exception, asyncio.CancelledError):
                await asyncio.shield(old.task)
            if self._by_key.get(key) is old:  # its done-callback has not run yet
                del self._by_key[key]

    def cancel(self, key: str) -> None:
        """Mark the run of ``key`` (if any) as asked to stop."""
        flight = self._by_key.get(key)
        if flight is not None:
            flight.cancelled = True
            flight.changed.set()

    def wake(self, key: str) -> None:
        """Tell the flight of ``key`` (if any) that its record may have changed."""
        flight = self._by_key.get(key)
        if flight is not None:
            flight.changed.set()

    def stop(self) -> None:
        """Cancel every flight's task (their records stay active: a live replica recovers
        them)."""
        for flight in list(self._by_key.values()):
            if flight.task is not None:
                flight.task.cancel()


async def wait(flight: Flight, waiter: asyncio.Future[Any] | None, timeout_s: float) -> None:
    """Until ``waiter`` is done, the flight is told of a change, or (no waiter)
    ``timeout_s`` [s] have passed."""
    changed = asyncio.ensure_future(flight.changed.wait())
    pending = {changed} | ({waiter} if waiter is not None else set())
    timeout = None if waiter is not None else timeout_s
    try:
        await asyncio.wait(pending, timeout=timeout, return_when=asyncio.FIRST_COMPLETED)
    finally:
        changed.cancel()
    flight.changed.clear()


async def look_up(store: Store, flight: Flight) -> asyncio.Future[Outcome] | None:
    """A look-up flight (:meth:`Runner.look_up_or_run`) the fast lane did not take: its
    lookup in a thread hop of its own, a ``hit`` outcome if found (None: not a look-up
    flight, or not stored: the ordinary path writes the record)."""
    if not flight.look_up:
        return None
    body = await asyncio.to_thread(store.get_result, flight.key)
    if body is None:
        return None
    found: asyncio.Future[Outcome] = asyncio.get_running_loop().create_future()
    found.set_result(Outcome(TaskStatus.HIT, body=body))
    return found
