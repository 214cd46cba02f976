"""The store's checkpoints of long computations (issue 22, defect 8), on SQLite and
PostgreSQL: kept only for the attempt holding the lease, one row per job generation,
gone when the job finishes; and the task's side (:class:`StoreCheckpoints`)."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import text

from service.store import StorageError, Store
from service.store.checkpoints import StoreCheckpoints

_keys = itertools.count()


#: PostgreSQL: a cluster of its own for the module (2-5 s to start): CI's slow step
@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.slow)])
def store(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Store]:
    url = (
        request.getfixturevalue("postgres")
        if request.param == "postgresql"
        else tmp_path / "db.sqlite3"
    )
    s = Store(url, cache_max_bytes=10_000, memory_cache_bytes=0)
    yield s
    s.close()


def _running(store: Store, owner: str = "attempt-1") -> str:
    """A new job (a key unique over the module's PostgreSQL database) leased to ``owner``."""
    key = f"ck-{next(_keys)}"
    store.enqueue_job(key, "simulation", {"k": key})
    assert store.claim(key, owner, "worker-1", 10.0).outcome == "claimed"
    return key


def test_only_the_lease_holder_keeps_one_checkpoint_per_generation(store: Store) -> None:
    key = _running(store)
    assert store.load_checkpoint(key, 1) is None
    assert store.save_checkpoint(key, 1, "attempt-1", b"first")
    assert store.save_checkpoint(key, 1, "attempt-1", b"second")  # replaces it
    assert store.load_checkpoint(key, 1) == b"second"
    assert store.checkpoint_sizes()[key] == len(b"second")
    assert not store.save_checkpoint(key, 1, "someone-else", b"stray")  # not its lease
    assert not store.save_checkpoint(key, 2, "attempt-1", b"other generation")
    assert store.load_checkpoint(key, 1) == b"second"
    assert store.load_checkpoint(key, 2) is None
    # the next attempt (after the first stopped heartbeating) reads it and writes its own
    assert store.claim(key, "attempt-2", "worker-2", 0.0).outcome == "claimed"
    assert store.load_checkpoint(key, 1) == b"second"
    assert not store.save_checkpoint(key, 1, "attempt-1", b"late")  # the old attempt lost it
    assert store.save_checkpoint(key, 1, "attempt-2", b"third")
    assert store.load_checkpoint(key, 1) == b"third"


@pytest.mark.parametrize("end", ["succeeded", "failed", "cancelled"])
def test_a_finished_job_has_no_checkpoint(store: Store, end: str) -> None:
    key = _running(store)
    assert store.save_checkpoint(key, 1, "attempt-1", b"state")
    if end == "cancelled":
        store.request_cancel(key)
    elif end == "succeeded":
        assert store.finish_with_result(key, "attempt-1", "simulation", b"{}")
    else:
        assert store.finish_job(key, "failed", {"detail": "x"}, owner="attempt-1")
    assert store.load_checkpoint(key, 1) is None
    assert key not in store.checkpoint_sizes()
    assert not store.save_checkpoint(key, 1, "attempt-1", b"after the end")


def test_prune_removes_checkpoints_of_inactive_jobs(store: Store) -> None:
    """A row left behind (written around a finish by another path) is removed by the
    periodic prune; an active job's row is kept."""
    live, done = _running(store), _running(store)
    store.save_checkpoint(live, 1, "attempt-1", b"live")
    store.finish_job(done, "failed", None)
    with store.engine.begin() as conn:  # a stray row, as a race would leave it
        conn.execute(
            text(
                "INSERT INTO checkpoints (key, generation, body, size, written) "
                "VALUES (:k, 1, :b, 1, 0)"
            ),
            {"k": done, "b": b"x"},
        )
    store.prune_jobs(older_than=0.0)
    sizes = store.checkpoint_sizes()
    assert live in sizes and done not in sizes


def test_task_side_reads_once_and_survives_a_failing_store(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    key = _running(store)
    store.save_checkpoint(key, 1, "attempt-1", b"earlier attempt")
    cp = StoreCheckpoints(store, key, 1, "attempt-1", interval_s=5.0, max_bytes=1000)
    reads = []
    real = store.load_checkpoint
    monkeypatch.setattr(store, "load_checkpoint", lambda *a: reads.append(a) or real(*a))
    assert cp.load() == b"earlier attempt" and cp.load() == b"earlier attempt"
    assert len(reads) == 1  # one read per attempt, however many solves ask
    cp.save(b"mine")
    assert cp.load() is None and cp.saved == 1  # superseded by this attempt's own
    assert store.load_checkpoint(key, 1) == b"mine"

    def broken(*_: object) -> bool:
        raise StorageError("disk full", full=True)

    monkeypatch.setattr(store, "save_checkpoint", broken)
    cp.save(b"lost")  # logged, not raised: a checkpoint is an optimisation
    assert cp.saved == 1
    monkeypatch.setattr(store, "load_checkpoint", broken)
    fresh = StoreCheckpoints(store, key, 1, "attempt-1", interval_s=5.0, max_bytes=1000)
    assert fresh.load() is None


def test_a_first_attempt_reads_no_checkpoint(store: Store) -> None:
    """A job's first attempt at a generation cannot find a checkpoint, so it asks the store
    nothing (a cold request pays no query); a retried attempt reads the one left."""
    key = "k-first"
    store.enqueue_and_claim(key, "simulation", {}, "attempt-1", "w1", refresh=False)
    assert store.save_checkpoint(key, 1, "attempt-1", b"progress")
    first = StoreCheckpoints(store, key, 1, "attempt-1", 5.0, 1000, resumable=False)
    assert first.load() is None
    retried = StoreCheckpoints(store, key, 1, "attempt-1", 5.0, 1000, resumable=True)
    assert retried.load() == b"progress"
