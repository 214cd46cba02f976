"""The store's durable job queue (issue 22, defect 4) and what the quotas count: a bound
that holds across writers, order within a client, fairness between clients, and no job
taken by two replicas, on SQLite and PostgreSQL."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest

from service.store import Store
from tests.service.store.locks import finishes_under_write_lock


def _store(url: str | Path) -> Store:
    return Store(url, cache_max_bytes=10_000, memory_cache_bytes=0)


def _queue(store: Store, key: str, who: str = "a", bound: int = 100, cost: float = 0.0) -> bool:
    time.sleep(0.002)  # distinct creation times: the order is the test's
    return store.queue_job(key, "test-sleep", {"k": key}, bound=bound, principal=who, cost=cost)[1]


def test_the_bound_refuses_new_jobs_not_joins(tmp_path: Path) -> None:
    store = _store(tmp_path / "db.sqlite3")
    assert _queue(store, "a1", bound=2) and _queue(store, "a2", bound=2)
    assert not _queue(store, "a3", bound=2)  # two wait already
    assert store.get_job("a3") is None
    assert _queue(store, "a1", bound=2)  # the same job again: joined, not a new one
    assert store.waiting_jobs() == 2
    job = store.get_job("a1")
    assert job is not None and job.waiting and job.principal == "a"
    # one taken by a replica: room for another
    assert [j.key for j in store.claim_waiting("r1", 1)] == ["a1"]
    assert _queue(store, "a3", bound=2)


def test_waiting_jobs_are_not_stale_and_a_direct_request_takes_one_over(tmp_path: Path) -> None:
    """Nobody holds a waiting job, so it never goes stale (no replica recovers it out of
    its turn); a synchronous request for the same key drives it at once (enqueue_job)."""
    store = _store(tmp_path / "db.sqlite3")
    _queue(store, "k")
    assert store.stale_jobs(0.0) == []
    job = store.enqueue_job("k", "test-sleep", {"k": "k"}, dispatcher="replica-1")
    assert job.dispatcher == "replica-1" and not job.waiting and job.generation == 1
    assert store.claim_waiting("replica-2", 5) == []
    assert [j.key for j in store.stale_jobs(0.0)] == ["k"]


def test_claims_are_in_order_within_a_client_and_fair_between_clients(tmp_path: Path) -> None:
    """Client a queues 4 jobs, then b 2: each next job goes to the client with fewer jobs
    taken (then the one waiting longest), so b's first job is second, not fifth."""
    store = _store(tmp_path / "db.sqlite3")
    for i in range(4):
        _queue(store, f"a{i}", "a")
    for i in range(2):
        _queue(store, f"b{i}", "b")
    order = [j.key for _ in range(6) for j in store.claim_waiting("r", 1)]
    assert order == ["a0", "b0", "a1", "b1", "a2", "a3"]


def test_with_one_worker_the_clients_take_turns(tmp_path: Path) -> None:
    """One job at a time (each finished before the next claim): the client served longest
    ago goes next, so b's two jobs are not left behind a's backlog of four."""
    store = _store(tmp_path / "db.sqlite3")
    for i in range(4):
        _queue(store, f"a{i}", "a")
    for i in range(2):
        _queue(store, f"b{i}", "b")
    order = []
    while got := store.claim_waiting("r", 1):
        order.append(got[0].key)
        store.finish_job(got[0].key, "succeeded")
        time.sleep(0.002)
    assert order == ["a0", "b0", "a1", "b1", "a2", "a3"]


def test_a_batch_claim_is_fair_too_and_respects_the_concurrency_quota(tmp_path: Path) -> None:
    store = _store(tmp_path / "db.sqlite3")
    for i in range(3):
        _queue(store, f"a{i}", "a")
    _queue(store, "b0", "b")
    assert [j.key for j in store.claim_waiting("r", 3)] == ["a0", "b0", "a1"]
    # a has 2 active, b 1: with a quota of 2 per client, a's last job waits
    assert store.claim_waiting("r", 3, per_principal=2) == []
    store.finish_job("a0", "succeeded")
    assert [j.key for j in store.claim_waiting("r", 3, per_principal=2)] == ["a2"]


def test_usage_counts_active_waiting_and_recent_cost(tmp_path: Path) -> None:
    store = _store(tmp_path / "db.sqlite3")
    _queue(store, "a0", "a", cost=0.25)
    _queue(store, "a1", "a", cost=0.5)
    _queue(store, "b0", "b", cost=1.0)
    store.claim_waiting("r", 1)  # a0
    usage = store.usage("a")
    assert (usage.active, usage.waiting) == (1, 1)
    assert usage.cost == pytest.approx(0.75, abs=1e-12)  # stored floats, summed by SQL
    a0 = store.get_job("a0")
    assert a0 is not None and usage.oldest == a0.created
    assert store.usage("a", window_s=0.0).cost == 0.0  # nothing started in the last 0 s
    assert store.usage("nobody") == type(usage)(0, 0, 0.0, None)


def _race(urls: list[str], jobs: int) -> dict[str, list[str]]:
    """``jobs`` queued jobs taken one at a time by 4 threads, each its own Store (a
    replica), until none waits: which replica took which keys."""
    seed = _store(urls[0])
    for i in range(jobs):
        seed.queue_job(f"j{i}", "test-sleep", {"i": i}, bound=jobs, principal=f"c{i % 3}")
    taken: dict[str, list[str]] = {}
    start = threading.Barrier(4)

    def replica(name: str, url: str) -> None:
        store = _store(url)
        start.wait()
        mine = taken.setdefault(name, [])
        while got := store.claim_waiting(name, 1):
            mine.extend(j.key for j in got)

    threads = [
        threading.Thread(target=replica, args=(f"r{i}", urls[i % len(urls)])) for i in range(4)
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    return taken


def _check_taken_once(store: Store, taken: dict[str, list[str]], jobs: int) -> None:
    keys = [k for ks in taken.values() for k in ks]
    assert sorted(keys) == sorted(f"j{i}" for i in range(jobs))  # each exactly once
    for name, ks in taken.items():
        for k in ks:
            job = store.get_job(k)
            assert job is not None and job.dispatcher == name


def test_four_replicas_on_one_sqlite_file_take_each_job_once(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'db.sqlite3'}"
    taken = _race([url], 60)
    _check_taken_once(_store(url), taken, 60)


def test_four_replicas_on_postgresql_take_each_job_once(postgres: str) -> None:
    """On PostgreSQL (READ COMMITTED) the replicas' claims really overlap: a second UPDATE
    of a row waits for the first to commit, re-reads it and matches nothing."""
    from sqlalchemy import text

    store = _store(postgres)
    with store.engine.begin() as conn:  # the module's database is shared: start empty
        conn.execute(text("DELETE FROM jobs"))
    taken = _race([postgres], 60)
    _check_taken_once(store, taken, 60)
    usage = store.usage("c0")
    assert usage.waiting == 0 and usage.active == 20


def test_an_empty_queue_is_claimed_without_the_write_lock(tmp_path: Path) -> None:
    """The dispatcher claims each time one of the replica's computations ends: with
    nothing waiting, the claim is a read and does not wait for (or hold) the write lock
    that the next request's record and result need.  It runs in a thread while this test
    holds SQLite's write lock (:func:`finishes_under_write_lock`); with a job waiting it
    still takes the lock and the job."""
    store = _store(tmp_path / "db.sqlite3")
    store.enqueue_job("running", "test-sleep", {"k": 1})  # active, driven: not waiting
    got: list[object] = []
    claim = lambda: got.append(store.claim_waiting("r", 2))  # noqa: E731
    returned = finishes_under_write_lock(tmp_path / "db.sqlite3", claim)
    assert returned, "a claim of an empty queue waited for the write lock"
    assert got == [[]]
    assert _queue(store, "w1")
    assert [j.key for j in store.claim_waiting("r", 2)] == ["w1"]
