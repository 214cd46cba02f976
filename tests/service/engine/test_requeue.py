"""A job taken from the durable queue by a replica that died before starting it goes back
to the queue and waits for a free slot (issue 22, the queue's loose end).  Before, the
first replica to notice its stale record drove it at once, beyond that replica's slots:
with its one worker busy, it had two computations in flight.

The app's real engine (one embedded Dask worker, no fast lane); the dead replica is a
record taken from the queue under another replica's name that never starts it."""

from __future__ import annotations

import hashlib
import time
from pathlib import Path

import pytest
from sqlalchemy import update

from service.store import Store
from service.store.tables import jobs
from tests.service.conftest import TERMINAL, make_client, wait_job, wait_ready

#: the orphan job's key (a parameter hash's shape: the job routes take no other)
ORPHAN = hashlib.sha256(b"orphan").hexdigest()
#: one slot, a replica silent for 1 s is dead (the monitor looks every 0.5 s)
SETTINGS = dict(
    workers=1,
    queue_size=0,
    fast_lane_threads=0,
    progress_interval_s=0.05,
    stale_after_s=1.0,
)


@pytest.mark.slow  # a real engine, a gate job and three stale periods: 6-10 s
def test_a_job_taken_by_a_dead_replica_waits_for_a_free_slot(tmp_path: Path) -> None:
    with make_client(tmp_path, **SETTINGS) as c:
        wait_ready(c)
        runner = c.app.state.runner  # type: ignore[attr-defined]
        store: Store = c.app.state.store  # type: ignore[attr-defined]
        gate = c.post("/test/sleep-jobs", json={"seconds": 30, "tag": "gate"}).json()["key"]
        wait_job(c, gate, lambda j: j["progress"] > 0 or j["status"] in TERMINAL)
        # the ghost replica takes a job from the queue and dies before starting it
        spec = {"seconds": 0.2, "tag": "orphan"}
        assert store.queue_job(ORPHAN, "test-sleep", spec, bound=10)[1]
        assert [j.key for j in store.claim_waiting("ghost", 1)] == [ORPHAN]
        # three stale periods: the monitor has looked at it several times
        end = time.monotonic() + 3.0
        while time.monotonic() < end:
            assert runner.in_flight <= 1, "driven beyond the replica's one slot"
            time.sleep(0.05)
        job = store.get_job(ORPHAN)
        assert job is not None and job.waiting and job.attempts == 0, job
        # the slot frees up: the job is dispatched in its turn and runs once
        assert c.delete(f"/v1/jobs/{gate}").status_code in (200, 202)
        done = wait_job(c, ORPHAN, timeout=60)
        assert done["status"] == "succeeded" and done["attempts"] == 1, done
        record = store.get_job(ORPHAN)
        assert record is not None and record.dispatcher == runner.replica


def test_requeue_takes_back_only_stale_jobs_nobody_started(tmp_path: Path) -> None:
    """The store's side: a taken job whose replica is fresh, and a running job, stay."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10_000, memory_cache_bytes=0)
    for key in ("fresh", "dead", "started"):
        store.queue_job(key, "test-sleep", {"k": key}, bound=10)
        time.sleep(0.002)
    assert len(store.claim_waiting("r", 3)) == 3
    assert store.claim("started", "attempt", "worker", 10.0).outcome == "claimed"
    with store.engine.begin() as conn:
        conn.execute(update(jobs).where(jobs.c.key != "fresh").values(heartbeat=0.0))
    assert store.requeue_stale(5.0) == ["dead"]
    waiting = {k: store.get_job(k).waiting for k in ("fresh", "dead", "started")}  # type: ignore[union-attr]
    assert waiting == {"fresh": False, "dead": True, "started": False}
    assert [j.key for j in store.claim_waiting("r2", 5)] == ["dead"]
    store.close()
