"""The monitor on its own (:class:`service.engine.monitor.Monitor`): the real store, the
flight table, and the callbacks the runner would hand it recorded.  Stale leases, worker
loss and restarts end to end are in ``test_restart.py``, ``test_requeue.py`` and
``test_faults.py``."""

from __future__ import annotations

import asyncio
import time
from pathlib import Path
from typing import Any

from service.engine.flight import Flight, Flights
from service.engine.lifecycle import ClaimOutcome, JobState
from service.engine.monitor import Monitor
from service.keys import Keyed, keyed
from service.settings import Settings
from service.store import Job, Store
from tests.service.kinds_for_tests import SLEEP, SleepSpec

STALE_S = 1.0  # the leases' stale timeout of these tests [s] (a loaded machine: > 1 look)


def _job(tag: str) -> Keyed:
    return keyed(SLEEP, SleepSpec(seconds=0.0, tag=tag))


class Calls:
    """What the monitor called back."""

    def __init__(self) -> None:
        self.ended: list[str] = []
        self.requeued = 0
        self.recovered: list[str] = []
        self.watched: list[str] = []


def _monitor(tmp_path: Path) -> tuple[Monitor, Calls]:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**7, memory_cache_bytes=0)
    calls = Calls()

    async def recover(job: Job) -> None:
        calls.recovered.append(job.key)

    def requeued() -> None:
        calls.requeued += 1

    monitor = Monitor(
        Settings(data_dir=tmp_path, stale_after_s=STALE_S),
        store,
        Flights(4, lambda flight, freed: None),
        watched=lambda: calls.watched,
        ended=calls.ended.append,
        requeued=requeued,
        recover=recover,
        poll_s=60.0,
    )
    return monitor, calls


def _flight(monitor: Monitor, job: Keyed) -> Flight:
    """A flight in the table whose task waits forever (the monitor only wakes it)."""

    async def drive(flight: Flight) -> bytes:
        await asyncio.Event().wait()
        return b""

    return monitor.flights.start(Flight(job), drive)


def test_a_stale_lease_is_recovered_and_an_ended_record_wakes_its_waiters(
    tmp_path: Path,
) -> None:
    """A running job whose heartbeat went stale and that no flight here drives is handed
    to ``recover``; a flight whose lease went stale is woken; a long-polled job no flight
    drives that ended calls ``ended``."""
    monitor, calls = _monitor(tmp_path)
    store = monitor.store
    orphan, mine, polled = _job("orphan"), _job("mine"), _job("polled")
    for job in (orphan, mine, polled):
        store.enqueue_job(job.key, SLEEP.name, job.canonical)
        assert store.claim(job.key, "owner", "worker-1", STALE_S).outcome == ClaimOutcome.CLAIMED
    store.finish_job(polled.key, JobState.SUCCEEDED)
    calls.watched.append(polled.key)

    async def scenario() -> Flight:
        flight = _flight(monitor, mine)
        await monitor.once()  # the leases are fresh: nothing to do
        assert calls.recovered == [] and not flight.changed.is_set()
        assert calls.ended == [polled.key]
        time.sleep(STALE_S * 1.5)
        await monitor.once()
        assert flight.changed.is_set()  # its lease is dead: its driving loop looks
        assert calls.recovered == [orphan.key]  # ours is not recovered twice
        return flight

    flight = asyncio.run(scenario())
    assert flight.task is not None and flight.task.done()  # cancelled with the loop


def test_a_lost_worker_ends_its_leases_at_once(tmp_path: Path) -> None:
    """The cluster's ``remove-worker`` event: the leases that worker held are dated back,
    so they are stale now, and the flights driving them are woken."""
    monitor, _ = _monitor(tmp_path)
    store = monitor.store
    job = _job("on-worker-1")
    store.enqueue_job(job.key, SLEEP.name, job.canonical)
    store.claim(job.key, "owner", "worker-1", STALE_S)

    async def scenario() -> Flight:
        flight = _flight(monitor, job)
        await monitor.worker_lost("worker-2")  # not its worker
        assert not flight.changed.is_set()
        await monitor.worker_lost("worker-1")
        assert flight.changed.is_set()
        return flight

    asyncio.run(scenario())
    assert [j.key for j in store.stale_jobs(STALE_S)] == [job.key]


def test_a_failure_the_store_refused_is_written_once_it_takes_writes(tmp_path: Path) -> None:
    """:meth:`Monitor.fail_later`: written at the monitor's next look with a healthy store."""
    monitor, _ = _monitor(tmp_path)
    store = monitor.store
    job = _job("unstored")
    store.enqueue_job(job.key, SLEEP.name, job.canonical)
    doc: dict[str, Any] = {"type": "storage", "detail": "the result could not be stored: full"}
    monitor.fail_later(job.key, doc)
    asyncio.run(monitor.once())
    record = store.get_job(job.key)
    assert record is not None and record.status == JobState.FAILED and record.error == doc
    assert monitor.pending_failures == {}
