"""Who may follow and cancel a job record (issue 34, item 3): the grants of the clients
that joined another client's run, per generation, their pruning, and the cancel that
holds only for the run's own client."""

from __future__ import annotations

from pathlib import Path

from service.store import Store
from service.store.tables import job_grants


def _store(tmp_path: Path) -> Store:
    return Store(tmp_path / "db.sqlite3", cache_max_bytes=10_000, memory_cache_bytes=0)


def test_a_record_is_seen_by_its_client_and_the_clients_granted_its_run(tmp_path: Path) -> None:
    store = _store(tmp_path)
    assert store.job_seen_by("k", "alice") == (None, False)
    store.enqueue_job("k", "simulation", {}, principal="alice")
    job, seen = store.job_seen_by("k", "alice")
    assert job is not None and job.principal == "alice" and seen
    assert store.job_seen_by("k", "bob")[1] is False
    store.enqueue_job("k", "simulation", {}, principal="bob")  # joins the active run
    assert store.get_job("k").principal == "alice"  # type: ignore[union-attr]
    store.grant("k", "bob", job.generation)
    assert store.job_seen_by("k", "bob")[1] is True
    assert store.job_seen_by("k", "carol")[1] is False
    # the run ends; carol's request starts a new one (a new generation, hers): bob's grant
    # was for the old run, alice's record is carol's now
    store.finish_job("k", "failed", {"detail": "x"})
    store.enqueue_job("k", "simulation", {}, principal="carol")
    new = store.get_job("k")
    assert new is not None and new.principal == "carol" and new.generation == job.generation + 1
    assert [store.job_seen_by("k", p)[1] for p in ("alice", "bob", "carol")] == [
        False,
        False,
        True,
    ]
    # pruning drops the grants of runs that are over, and of records that are gone
    store.grant("k", "dave", new.generation)
    assert store.prune_jobs(older_than=0.0) == 0  # the record is active: kept
    assert store.job_seen_by("k", "dave")[1] is True
    with store._read() as conn:
        rows = conn.execute(job_grants.select().order_by(job_grants.c.principal)).all()
    assert [r.principal for r in rows] == ["dave"]
    store.finish_job("k", "succeeded")
    assert store.prune_jobs(older_than=float("inf")) == 1
    assert store.job_seen_by("k", "dave") == (None, False)
    with store._read() as conn:
        assert conn.execute(job_grants.select()).all() == []


def test_cancel_for_a_client_holds_only_for_its_own_run(tmp_path: Path) -> None:
    store = _store(tmp_path)
    store.enqueue_job("k", "simulation", {}, principal="alice")
    job = store.request_cancel("k", "bob")
    assert job is not None and job.status == "queued" and not job.cancel  # not bob's run
    job = store.request_cancel("k", "alice")
    assert job is not None and job.status == "cancelled" and job.cancel
    store.enqueue_job("k", "simulation", {}, principal="bob")  # a new run, bob's
    job = store.request_cancel("k")  # no client named: an admin's, or keys off
    assert job is not None and job.status == "cancelled"
