"""The fast lane on its own (:class:`service.engine.lane.FastLane`): no runner, no Dask,
the real store and a real thread.  What it takes, that it can be turned off, and that its
first attempt writes the record already leased, computes it and finishes it.  The server's
side (a request through the lane, its hand-off to a worker) is in ``test_fast_lane.py``."""

from __future__ import annotations

import asyncio
from dataclasses import replace
from pathlib import Path

import pytest

from service.engine.flight import Flight
from service.engine.lane import FastLane
from service.engine.lifecycle import JobState, TaskStatus
from service.engine.task import TaskConfig
from service.keys import Keyed, keyed
from service.settings import Settings
from service.store import Store
from tests.service.kinds_for_tests import SLEEP, SleepSpec


def _lane(tmp_path: Path, **settings: float) -> tuple[FastLane, Store]:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**7, memory_cache_bytes=0)
    s = Settings(data_dir=tmp_path, fast_lane_max_metered_s=0.0, **settings)  # type: ignore[arg-type]

    def config() -> TaskConfig:
        return TaskConfig(
            db_url=store.url,
            cache_max_bytes=store.cache_max_bytes,
            timeout_s=30.0,
            progress_interval_s=0.05,
            stale_after_s=10.0,
            grace_s=5.0,
        )

    return FastLane(s, store, "replica-a", config), store


def _sleep(estimate_s: float | None, tag: str = "") -> Keyed:
    return keyed(SLEEP, SleepSpec(seconds=0.0, estimate_s=estimate_s, tag=tag))


def test_turned_off_it_takes_nothing(tmp_path: Path) -> None:
    """``fast_lane_threads=0`` (or ``fast_lane_max_s=0``): every attempt goes to a worker,
    and a run asked of it anyway is refused, not run."""
    for off in ({"fast_lane_threads": 0}, {"fast_lane_max_s": 0.0}):
        lane, _ = _lane(tmp_path, **off)
        assert not lane.on
        assert lane.takes(_sleep(0.001), None) == (False, None)
        with pytest.raises(RuntimeError, match="off"):
            lane.run(Flight(_sleep(0.001)), "key")
        assert lane.runs == lane.busy == 0


def test_takes_a_first_attempt_estimated_under_its_limit(tmp_path: Path) -> None:
    """Taken: a new record estimated at most ``fast_lane_max_s``.  Not taken: an estimate
    over it or none (no metered work), a job that started before or was handed off, a
    resubmission, or no free thread."""
    lane, store = _lane(tmp_path, fast_lane_threads=1, fast_lane_max_s=0.05)
    small = _sleep(0.01)
    assert lane.takes(small, None) == (True, None)
    assert lane.takes(_sleep(0.06), None) == (False, None)
    assert lane.takes(_sleep(None), None) == (False, None)
    record = store.enqueue_job(small.key, SLEEP.name, small.canonical)
    assert lane.takes(small, record) == (True, None)  # queued, never started: a first attempt
    assert lane.takes(small, replace(record, attempts=1)) == (False, None)
    handed = replace(record, last_retry_reason="handed off to a worker by the fast lane: x")
    assert lane.takes(small, handed) == (False, None)
    assert lane.takes(small, record, resubmits=1) == (False, None)
    lane.busy = 1  # its one thread computing
    assert lane.takes(small, None) == (False, None)


def test_first_attempt_writes_the_record_leased_and_finishes_it(tmp_path: Path) -> None:
    """:meth:`FastLane.first` answers once the record is written (no outcome yet needed),
    and the run then stores the result and finishes the record itself, with the body in
    its answer; a look-up flight of the stored key is a hit that writes nothing."""
    lane, store = _lane(tmp_path, fast_lane_threads=1, fast_lane_max_s=0.05)
    job = _sleep(0.01, tag="first")

    async def scenario() -> None:
        known, waiter = await lane.first(Flight(job), force=False)
        assert known is None and waiter is not None
        outcome = await waiter
        assert outcome.status == TaskStatus.SUCCEEDED and outcome.finished
        assert outcome.body is not None and b'"slept"' in outcome.body
        record = store.get_job(job.key)
        assert record is not None and record.status == JobState.SUCCEEDED
        assert record.dispatcher == "replica-a" and record.attempts == 1
        assert (lane.claimed, lane.runs) == (1, 1)

        known, waiter = await lane.first(Flight(job, look_up=True), force=False)
        assert known is None and waiter is not None
        hit = await waiter
        assert hit.status == TaskStatus.HIT and hit.body == outcome.body
        assert (lane.claimed, lane.runs) == (1, 1)  # a hit is no run
        for _ in range(100):  # the threads' release comes back through the event loop
            if lane.busy == 0:
                break
            await asyncio.sleep(0.01)
        assert lane.busy == 0

    asyncio.run(scenario())
    lane.shutdown()
