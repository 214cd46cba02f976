"""The durable queue's dispatcher on its own (:class:`service.engine.dispatcher.Dispatcher`):
the real store, no runner, no Dask; what it drives is recorded by the callback the runner
would hand it.  The server's side (fairness, quotas, restarts) is in ``test_queue.py``."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from service.engine.dispatcher import Dispatcher
from service.engine.outcome import QueueFull
from service.keys import Keyed, keyed
from service.settings import Settings
from service.store import Job, Store
from tests.service.kinds_for_tests import SLEEP, SleepSpec


def _job(tag: str) -> Keyed:
    return keyed(SLEEP, SleepSpec(seconds=0.0, tag=tag))


def _dispatcher(tmp_path: Path, free: list[int], driven: list[str], **settings: int) -> Dispatcher:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**7, memory_cache_bytes=0)

    async def drive(job: Job) -> None:
        driven.append(job.spec["tag"])

    connected = asyncio.Event()
    connected.set()
    return Dispatcher(
        Settings(data_dir=tmp_path, **settings),  # type: ignore[arg-type]
        store,
        "replica-a",
        connected=connected,
        free_slots=lambda: free[0],
        drive=drive,
        poll_s=60.0,
    )


def test_takes_as_many_waiting_jobs_as_free_slots_in_order(tmp_path: Path) -> None:
    """No free slot: the jobs wait (accepted all the same); then each round takes at most
    the free slots, oldest first, and says when it found the queue drained (a flight that
    ends then does not wake it; a job queued does)."""
    free, driven = [0], []
    d = _dispatcher(tmp_path, free, driven)

    async def scenario() -> None:
        for tag in ("a", "b", "c"):
            record = await d.enqueue(_job(tag))
            assert record.waiting
        assert driven == [] and d.dispatched == 0
        free[0] = 2
        await d.once()
        assert driven == ["a", "b"] and d.dispatched == 2 and not d.drained
        await d.once()
        assert driven == ["a", "b", "c"] and d.drained  # one taken of two free: none left
        d._kick.clear()
        d.slot_freed()
        assert not d._kick.is_set()  # drained: a flight that ends leaves it asleep
        d.kick()
        assert d._kick.is_set()

    asyncio.run(scenario())
    record = d.store.get_job(_job("a").key)
    assert record is not None and record.dispatcher == "replica-a"


def test_a_full_queue_refuses_the_job(tmp_path: Path) -> None:
    """``max_queued_jobs`` jobs waiting: the next one is refused (:class:`QueueFull`), and
    nothing of it is written."""
    d = _dispatcher(tmp_path, [0], [], max_queued_jobs=1)

    async def scenario() -> None:
        await d.enqueue(_job("first"))
        with pytest.raises(QueueFull, match="1 jobs wait"):
            await d.enqueue(_job("second"))

    asyncio.run(scenario())
    assert d.store.get_job(_job("second").key) is None
