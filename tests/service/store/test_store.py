"""The store (SQLAlchemy Core on SQLite here): persistence, compression, bounded size with
LRU eviction, the memory front, job records, leases, migrations and the integrity check."""

from __future__ import annotations

import multiprocessing
import random
import sqlite3
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import event, text

from service.store import IDENTITY_MAX_BYTES, StorageError, Store, StoreRefused
from service.store import MemoryLRU as _MemoryLRU
from tests.service.store.locks import finishes_under_write_lock


def test_results_survive_reopening(tmp_path: Path) -> None:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10_000, memory_cache_bytes=1000)
    store.put_result("a", "simulation", b'{"x":1}')
    store.close()
    again = Store(tmp_path / "db.sqlite3", cache_max_bytes=10_000, memory_cache_bytes=1000)
    assert again.get_result("a") == b'{"x":1}'
    assert again.get_result("b") is None


def _incompressible(seed: int) -> bytes:
    """100 random bytes: zlib stores them in about 111 bytes (the bound counts stored size)."""
    return random.Random(seed).randbytes(100)


def test_disk_bound_evicts_least_recently_used(tmp_path: Path) -> None:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=250, memory_cache_bytes=0)
    for i, key in enumerate("abc"):
        store.put_result(key, "simulation", _incompressible(i))
    assert store.result_bytes() <= 250
    assert store.get_result("a") is None  # oldest went first
    assert store.get_result("c") is not None
    store.get_result("b")  # b is now more recent than c
    store.put_result("d", "simulation", _incompressible(3))
    assert store.get_result("c") is None
    assert store.get_result("b") is not None and store.get_result("d") is not None


def test_memory_hits_count_for_disk_eviction(tmp_path: Path) -> None:
    """A result served from the memory front is recently used on disk too: the disk
    bound evicts the result nobody asked for, not the hot one."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=250, memory_cache_bytes=1000)
    body = _incompressible(0)
    store.put_result("a", "simulation", body)
    store.put_result("b", "simulation", _incompressible(1))
    assert store.get_result("a") == body  # a memory hit: a is now more recent than b
    store.put_result("c", "simulation", _incompressible(2))
    assert store.get_result("b") is None
    assert store.get_result("a") == body and store.get_result("c") == _incompressible(2)


def test_memory_front_is_bounded() -> None:
    lru = _MemoryLRU(max_bytes=10)
    lru.put("a", b"12345")
    lru.put("b", b"12345")
    lru.get("a")
    lru.put("c", b"12345")
    assert lru.get("b") is None and lru.get("a") == b"12345" and lru.get("c") == b"12345"
    lru.put("huge", b"x" * 11)
    assert lru.get("huge") is None


def test_job_records(tmp_path: Path) -> None:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=1000, memory_cache_bytes=1000)
    store.enqueue_job("k", "simulation", {"modes": 2})
    job = store.get_job("k")
    assert job is not None and job.status == "queued" and job.spec == {"modes": 2}
    assert [j.key for j in store.active_jobs()] == ["k"]
    store.finish_job("k", "failed", {"detail": "boom"})
    job = store.get_job("k")
    assert job is not None and job.status == "failed" and job.error == {"detail": "boom"}
    store.finish_job("k", "succeeded")  # terminal states are final
    assert store.get_job("k").status == "failed"  # type: ignore[union-attr]
    assert store.prune_jobs(older_than=job.updated + 1) == 1
    assert store.get_job("k") is None


def _time_axis(n: int) -> bytes:
    """A JSON time axis of ``n`` samples (9 bytes each): compresses well over 2x."""
    return b'{"t":[' + b",".join(b"%.6f" % (i * 1e-3) for i in range(n)) + b"]}"


def _codecs(store: Store) -> dict[str, tuple[str, int]]:
    with store.engine.connect() as conn:
        rows = conn.execute(text("SELECT key, codec, size FROM results")).all()
    return {key: (codec, size) for key, codec, size in rows}


def test_results_are_stored_compressed(tmp_path: Path) -> None:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**7, memory_cache_bytes=0)
    body = _time_axis(20_000)
    assert len(body) > IDENTITY_MAX_BYTES
    store.put_result("a", "simulation", body)
    assert store.get_result("a") == body  # byte-exact round trip through zlib
    assert store.result_bytes() < len(body) / 2  # a time axis compresses well over 2x
    assert _codecs(store)["a"][0] == "zlib"


def test_small_results_are_stored_as_they_are(tmp_path: Path) -> None:
    """Bodies up to IDENTITY_MAX_BYTES are written with the ``identity`` codec (zlib's time
    is paid on every cold request, its bytes saved only bound the cache), by both writers
    (put_result; finish_with_result, what a task does); readers get the same bytes, and
    the disk bound counts what is stored: the raw size for them, the compressed one above."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**7, memory_cache_bytes=0)
    small, edge, big = _time_axis(2_000), b"x" * IDENTITY_MAX_BYTES, _time_axis(20_000)
    store.put_results({"small": ("simulation", small), "edge": ("simulation", edge)})
    store.put_result("big", "simulation", big)
    claim = store.enqueue_and_claim("task", "simulation", {}, "me", "here", refresh=False)
    assert claim.outcome == "claimed"
    assert store.finish_with_result("task", "me", "simulation", small, remember=False)
    codecs = _codecs(store)
    assert codecs["small"] == codecs["task"] == ("identity", len(small))
    assert codecs["edge"] == ("identity", IDENTITY_MAX_BYTES)
    assert codecs["big"][0] == "zlib" and codecs["big"][1] < len(big) / 2
    for key, body in (("small", small), ("edge", edge), ("big", big), ("task", small)):
        assert store.get_result(key) == body
    assert store.result_bytes() == sum(size for _, size in codecs.values())
    assert _stats(store) == _table_totals(store)
    # a store told to compress everything (identity_max_bytes=0) writes zlib rows, which
    # the default store reads back: a replica of either setting reads the other's rows
    other = Store(tmp_path / "db.sqlite3", 10**7, 0, identity_max_bytes=0)
    other.put_result("small2", "simulation", small)
    assert _codecs(store)["small2"][0] == "zlib" and store.get_result("small2") == small


def _old_schema(path: Path) -> None:
    """The database the hand-written sqlite3 store (before alembic) wrote."""
    conn = sqlite3.connect(path)
    conn.executescript(
        """
        CREATE TABLE results (key TEXT PRIMARY KEY, kind TEXT NOT NULL, body BLOB NOT NULL,
            size INTEGER NOT NULL, created REAL NOT NULL, accessed REAL NOT NULL);
        CREATE INDEX results_accessed ON results (accessed);
        CREATE TABLE jobs (key TEXT PRIMARY KEY, kind TEXT NOT NULL, spec TEXT NOT NULL,
            status TEXT NOT NULL, progress REAL NOT NULL DEFAULT 0, error TEXT,
            created REAL NOT NULL, started REAL, finished REAL, updated REAL NOT NULL,
            cancel INTEGER NOT NULL DEFAULT 0);
        CREATE INDEX jobs_status ON jobs (status);
        INSERT INTO results VALUES ('old', 'simulation', CAST('{"x":1}' AS BLOB), 7, 1.0, 1.0);
        INSERT INTO jobs (key, kind, spec, status, created, updated)
            VALUES ('j', 'simulation', '{}', 'queued', 1.0, 1.0);
        """
    )
    conn.commit()
    conn.close()


def test_migrates_a_pre_alembic_database(tmp_path: Path) -> None:
    """The old file keeps its data: stamped 0001, migrated to head (codec, attempts, ...,
    the running totals of 0003, the queue's columns of 0004, the checkpoints of 0005, the
    job grants of 0006)."""
    path = tmp_path / "db.sqlite3"
    _old_schema(path)
    store = Store(path, cache_max_bytes=10_000, memory_cache_bytes=0)
    assert store.get_result("old") == b'{"x":1}'  # stored uncompressed: codec 'identity'
    job = store.get_job("j")
    assert job is not None and job.status == "queued" and job.attempts == 0
    assert job.refresh is False and job.last_retry_reason is None
    # migration 0004: an active job of before was being driven, not waiting in the queue
    assert job.dispatcher == "before-0004" and not job.waiting
    assert job.principal is None and job.cost == 0.0
    conn = sqlite3.connect(path)
    assert conn.execute("SELECT version_num FROM alembic_version").fetchone() == ("0006",)
    assert conn.execute("SELECT COUNT(*) FROM checkpoints").fetchone() == (0,)
    assert conn.execute("SELECT COUNT(*) FROM job_grants").fetchone() == (0,)
    # migration 0003 filled the running totals from the rows already there
    assert conn.execute("SELECT result_bytes, result_rows FROM store_stats").fetchall() == [(7, 1)]
    conn.close()
    assert store.result_bytes() == 7


def test_zero_length_file_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "db.sqlite3"
    path.touch()
    with pytest.raises(StoreRefused, match=r"empty \(0 bytes\).*backup.*move the file away"):
        Store(path, cache_max_bytes=1000, memory_cache_bytes=0)
    assert path.stat().st_size == 0  # left as found, not reinitialised


def test_damaged_file_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "db.sqlite3"
    store = Store(path, cache_max_bytes=10**6, memory_cache_bytes=0)
    for i in range(50):
        store.put_result(f"k{i}", "simulation", random.Random(i).randbytes(4000))
    store.close()
    data = bytearray(path.read_bytes())
    data[4096 * 3 : 4096 * 6] = b"\xa5" * (4096 * 3)  # overwrite pages 4-6 (b-tree pages)
    path.write_bytes(bytes(data))
    with pytest.raises(StoreRefused, match=r"damaged|not a readable") as info:
        Store(path, cache_max_bytes=1000, memory_cache_bytes=0)
    assert ".recover" in str(info.value) and "backup" in str(info.value)


def test_lease_claim_heartbeat_takeover(tmp_path: Path) -> None:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=1000, memory_cache_bytes=0)
    store.enqueue_job("k", "simulation", {})
    assert store.claim("k", "a1", "w1", stale_after_s=60).outcome == "claimed"
    # a second attempt respects the live lease
    assert store.claim("k", "a2", "w2", stale_after_s=60).outcome == "elsewhere"
    assert store.heartbeat("k", "a1", 0.5) == "ok"
    assert store.get_job("k").progress == 0.5  # type: ignore[union-attr]
    # a stale lease (heartbeat older than stale_after_s = 0) is taken over, with the reason
    time.sleep(0.01)
    claim = store.claim("k", "a2", "w2", stale_after_s=0.0)
    assert claim.outcome == "claimed" and claim.job is not None
    assert claim.job.attempts == 2 and claim.job.owner == "a2"
    assert "attempt 1 on w1 stopped heartbeating" in (claim.job.last_retry_reason or "")
    assert store.heartbeat("k", "a1", 0.9) == "lost"  # the old attempt learns it lost it
    assert store.finish_job("k", "succeeded", owner="a1") is False  # and cannot finish it
    store.request_cancel("k")
    assert store.heartbeat("k", "a2") == "cancelled"
    assert store.claim("k", "a3", "w3", stale_after_s=0.0).outcome == "done"
    # a finished job accepted again is a new generation with fresh attempts
    job = store.enqueue_job("k", "simulation", {}, refresh=True)
    assert (job.status, job.generation, job.attempts, job.refresh) == ("queued", 2, 0, True)


def test_expired_leases_of_a_lost_worker_are_taken_over_at_once(tmp_path: Path) -> None:
    """Dask's worker-loss signal (the runner's ``remove-worker`` event) ends the leases of
    that worker's jobs: another attempt claims them at once, with a stale_after_s of an
    hour; the jobs of other workers keep theirs."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=1000, memory_cache_bytes=0)
    for key in ("lost", "alive"):
        store.enqueue_job(key, "simulation", {})
    assert store.claim("lost", "a1", "tcp://w1:1", stale_after_s=3600).outcome == "claimed"
    assert store.claim("alive", "b1", "tcp://w2:1", stale_after_s=3600).outcome == "claimed"
    assert store.claim("lost", "a2", "tcp://w2:1", stale_after_s=3600).outcome == "elsewhere"
    expired = store.expire_leases("tcp://w1:1", time.time() - 3600)
    assert expired == ["lost"]
    claim = store.claim("lost", "a2", "tcp://w2:1", stale_after_s=3600)
    assert claim.outcome == "claimed" and claim.job is not None and claim.job.attempts == 2
    assert "attempt 1 on tcp://w1:1 stopped heartbeating" in (claim.job.last_retry_reason or "")
    assert store.claim("alive", "b2", "tcp://w3:1", stale_after_s=3600).outcome == "elsewhere"
    assert store.expire_leases("tcp://w1:1", time.time() - 3600) == []  # idempotent


def test_full_database_raises_storage_error_and_probe_recovers(tmp_path: Path) -> None:
    """SQLITE_FULL (a page limit here, a full disk in tests/service/engine/test_faults.py) is a
    StorageError with ``full``; the store is unhealthy until a probe write succeeds."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**8, memory_cache_bytes=0)
    limit = {"pages": 20}

    @event.listens_for(store.engine, "connect")
    def _cap(dbapi_conn: sqlite3.Connection, _: object) -> None:
        dbapi_conn.execute(f"PRAGMA max_page_count = {limit['pages']}")

    store.engine.dispose()
    with pytest.raises(StorageError) as info:
        store.put_result("big", "simulation", random.Random(0).randbytes(200_000))
    assert info.value.full and not store.healthy
    assert not store.probe()
    limit["pages"] = 1_000_000
    store.engine.dispose()
    assert store.probe() and store.healthy
    store.put_result("big", "simulation", random.Random(0).randbytes(200_000))


def test_a_result_read_without_remember_stays_out_of_memory(tmp_path: Path) -> None:
    """get_result(remember=False) answers the stored bytes and leaves the memory front as
    it was (the engine reads each fresh result that way); a plain read fills it."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**6, memory_cache_bytes=10**6)
    writer = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**6, memory_cache_bytes=0)
    body = b'{"t":[1.0,2.0]}'
    writer.put_result("a", "simulation", body)  # another process's store (a worker's)
    assert store.get_result("a", remember=False) == body
    assert store._memory.get("a") is None
    assert store.get_result("a") == body
    assert store._memory.get("a") == body


def test_batched_results_and_the_memo_over_them(tmp_path: Path) -> None:
    """put_results/get_results: one transaction, one query; StoreMemo keeps piece results
    (a study's case summaries) as rows of the kind its keys name, which no result key
    (SHA-256 hex) can reach."""
    from sqlalchemy import select

    from service.store.memo import StoreMemo
    from service.store.tables import results

    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**6, memory_cache_bytes=0)
    queries: list[str] = []
    rows: list[int] = []  # parameter sets of each statement

    @event.listens_for(store.engine, "before_cursor_execute")
    def _count(
        conn: object, cursor: object, statement: str, params: Any, context: object, many: bool
    ) -> None:
        queries.append(statement)
        rows.append(len(params) if many else 1)

    def statements(start: str) -> list[int]:
        """The parameter sets of each statement starting with ``start``."""
        pairs = zip(queries, rows, strict=True)
        return [n for q, n in pairs if q.lstrip().upper().startswith(start)]

    memo = StoreMemo(store)
    summaries = {f"study_case:{i:064x}": {"status": "ok", "peak": 1e-3 * i} for i in range(50)}
    memo.put_many(summaries)
    # one upsert statement executed for the 50 rows (50 single statements cost a study
    # of 10,000 cases seconds)
    assert statements("INSERT") == [50]
    queries.clear()
    rows.clear()
    read = time.time()
    keys = [*summaries, "study_case:" + "f" * 64]
    assert memo.get_many(keys) == summaries  # the missing key is absent
    selects = [s for s in queries if s.lstrip().upper().startswith("SELECT")]
    assert len(selects) == 1 and " IN " in selects[0]  # one query for the whole batch
    # the 50 reads are written to `accessed` (LRU) by the next write: one statement too
    queries.clear()
    rows.clear()
    memo.put_many({"study_case:" + "e" * 64: {"status": "ok"}})
    assert statements("UPDATE RESULTS") == [50]
    with store.engine.connect() as conn:
        accessed = dict(conn.execute(select(results.c.key, results.c.accessed)).all())
    assert all(accessed[k] >= read for k in summaries)  # each key's own read time
    with store.engine.connect() as conn:
        kinds = set(conn.execute(select(results.c.kind)).scalars())
    assert kinds == {"study_case"}
    assert store.get_result(f"{0:064x}") is None  # the bare case key holds no summary


def test_the_memo_reports_storage_failures_without_failing_the_computation(
    tmp_path: Path,
) -> None:
    from service.store.memo import StoreMemo

    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**8, memory_cache_bytes=0)

    @event.listens_for(store.engine, "connect")
    def _cap(dbapi_conn: sqlite3.Connection, _: object) -> None:
        dbapi_conn.execute("PRAGMA max_page_count = 20")

    store.engine.dispose()
    memo = StoreMemo(store)
    big = {"study_case:a": {"blob": random.Random(0).randbytes(200_000).hex()}}
    memo.put_many(big)  # logged, not raised
    assert not store.healthy and store.last_full  # the store says why (readiness, 507)
    assert memo.get_many(["study_case:a"]) == {}


# -- the running totals (store_stats) ---------------------------------------------------------


def _table_totals(store: Store) -> tuple[int, int]:
    """(SUM(size), COUNT(*)) of the results table, counted."""
    with store.engine.connect() as conn:
        size, rows = conn.execute(
            text("SELECT COALESCE(SUM(size), 0), COUNT(*) FROM results")
        ).one()
    return int(size), int(rows)


def _stats(store: Store) -> tuple[int, int]:
    with store.engine.connect() as conn:
        row = conn.execute(text("SELECT result_bytes, result_rows FROM store_stats")).one()
    return int(row[0]), int(row[1])


def _write_many(url: str, bound: int, writer: int, n: int) -> None:
    """``n`` puts by one writer with a store of its own (a process or a replica): new keys,
    overwrites of keys other writers also write (sizes differ), batches, evictions."""
    store = Store(url, cache_max_bytes=bound, memory_cache_bytes=0, migrate=False)
    rng = random.Random(writer)
    try:
        for i in range(n):
            size = rng.randrange(50, 400)
            if i % 5 == 4:  # a batch (the study memo's writes)
                store.put_results(
                    {f"w{writer}-b{i}-{j}": ("simulation", rng.randbytes(size)) for j in range(3)}
                )
            else:  # half on keys shared by all writers: overwrites with another size
                key = f"shared-{rng.randrange(8)}" if i % 2 else f"w{writer}-{i}"
                store.put_result(key, "simulation", rng.randbytes(size))
    finally:
        store.close()


def test_running_total_follows_writes_overwrites_and_evictions(tmp_path: Path) -> None:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=1000, memory_cache_bytes=0)
    assert _stats(store) == (0, 0) and store.result_bytes() == 0
    store.put_result("a", "simulation", _incompressible(0))
    store.put_result("a", "simulation", random.Random(9).randbytes(300))  # overwrite, larger
    assert _stats(store) == _table_totals(store) and _stats(store)[1] == 1
    for i in range(20):  # well past the bound: evictions on every write
        store.put_result(f"k{i}", "simulation", _incompressible(i))
    assert _stats(store) == _table_totals(store)
    assert store.result_bytes() == _table_totals(store)[0] <= 1000
    # the newest results are kept even when they alone exceed the bound
    store.put_results(
        {f"big{i}": ("simulation", random.Random(i).randbytes(800)) for i in range(2)}
    )
    assert _stats(store) == _table_totals(store) and _stats(store)[1] == 2
    assert store.recount_results() == _table_totals(store)


def test_running_total_is_exact_under_concurrent_threads(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'db.sqlite3'}"
    store = Store(url, cache_max_bytes=20_000, memory_cache_bytes=0)
    threads = [threading.Thread(target=_write_many, args=(url, 20_000, w, 40)) for w in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    size, rows = _table_totals(store)
    assert _stats(store) == (size, rows) and rows > 0
    assert size <= 20_000 + 3 * 450  # the bound, past it only by the newest write


def test_running_total_is_exact_under_concurrent_processes(tmp_path: Path) -> None:
    """Worker processes of one replica write to one SQLite file at once."""
    url = f"sqlite:///{tmp_path / 'db.sqlite3'}"
    store = Store(url, cache_max_bytes=20_000, memory_cache_bytes=0)
    ctx = multiprocessing.get_context("spawn")
    procs = [ctx.Process(target=_write_many, args=(url, 20_000, w, 40)) for w in range(3)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(timeout=120)
        assert p.exitcode == 0
    size, rows = _table_totals(store)
    assert _stats(store) == (size, rows) and rows > 0
    assert size <= 20_000 + 3 * 450


def test_the_migration_fills_the_running_total_and_a_restart_recounts(tmp_path: Path) -> None:
    """A database written before migration 0003 gets its totals from its rows; drift (a
    writer of an older version during a rolling upgrade) is corrected by the recount a
    replica does at start."""
    path = tmp_path / "db.sqlite3"
    store = Store(path, cache_max_bytes=10**6, memory_cache_bytes=0)
    for i in range(5):
        store.put_result(f"k{i}", "simulation", _incompressible(i))
    with store.engine.begin() as conn:  # an old writer: a row the totals do not know
        conn.execute(
            text("INSERT INTO results VALUES ('old', 'simulation', x'00', 1, 1.0, 1.0, 'identity')")
        )
    assert _stats(store) != _table_totals(store)
    assert store.recount_results() == _table_totals(store) == _stats(store)


@pytest.mark.slow  # a PostgreSQL cluster of its own (a few seconds)
def test_running_total_is_exact_on_postgresql(postgres: str) -> None:
    """Several replicas' stores (engines of their own) writing at once on PostgreSQL: the
    totals' row lock serialises the writers that change sizes, so the total stays exact
    (no lost update, no deadlock with evictions of rows another writer overwrites)."""
    store = Store(postgres, cache_max_bytes=20_000, memory_cache_bytes=0)
    with store.engine.begin() as conn:
        conn.execute(text("DELETE FROM results"))
    store.recount_results()
    threads = [
        threading.Thread(target=_write_many, args=(postgres, 20_000, w, 40)) for w in range(4)
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    size, rows = _table_totals(store)
    assert _stats(store) == (size, rows) and rows > 0
    assert size <= 20_000 + 3 * 450
    assert store.healthy
    store.close()


def test_a_request_joining_a_run_that_just_stored_its_result_does_not_reset_it(
    tmp_path: Path,
) -> None:
    """``enqueue_job(keep_stored=True)`` (a request joining an in-flight run, which may have
    just ended) leaves a succeeded job whose result is stored as it is: resetting it made a
    second computation of the same key (seen as 2 computations for 20 identical requests
    under load); without its result, or failed, or with ``refresh``, it is run again."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10_000, memory_cache_bytes=0)
    store.enqueue_job("k", "simulation", {})
    store.finish_job("k", "succeeded")
    # succeeded but its result not stored (evicted): accepted again, a new generation
    job = store.enqueue_job("k", "simulation", {}, keep_stored=True)
    assert (job.status, job.generation) == ("queued", 2)
    store.put_result("k", "simulation", b'{"ok": true}')
    store.finish_job("k", "succeeded")
    job = store.enqueue_job("k", "simulation", {}, keep_stored=True)
    assert (job.status, job.generation) == ("succeeded", 2)  # left as it is
    job = store.enqueue_job("k", "simulation", {}, refresh=True)  # the runner's refresh
    assert (job.status, job.generation) == ("queued", 3)  # computed again


def test_enqueue_and_claim_writes_the_record_already_leased(tmp_path: Path) -> None:
    """The fast lane's first attempt: record and lease in one transaction (one BEGIN), the
    record running under the attempt from its first moment; an active record is left to
    its owner, a stored result finishes the job instead, a finished one is a new
    generation."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10_000, memory_cache_bytes=0)
    begins: list[str] = []

    @event.listens_for(store.engine, "before_cursor_execute")
    def _count(conn: object, cursor: object, statement: str, *args: object) -> None:
        if statement.startswith("BEGIN"):
            begins.append(statement)

    claim = store.enqueue_and_claim("k", "simulation", {"m": 1}, "a1", "w1", refresh=False)
    assert begins == ["BEGIN IMMEDIATE"]  # one write transaction
    job = claim.job
    assert claim.outcome == "claimed" and job is not None
    assert (job.status, job.owner, job.worker, job.attempts, job.generation) == (
        "running",
        "a1",
        "w1",
        1,
        1,
    )
    assert job.spec == {"m": 1} and job.started is not None and job.heartbeat is not None
    assert store.heartbeat("k", "a1", 0.5) == "ok"  # the lease is the one claim gives
    # an active record is not claimed twice: the second caller goes the ordinary way
    again = store.enqueue_and_claim("k", "simulation", {"m": 1}, "a2", "w2", refresh=False)
    assert again.outcome == "queued" and again.job is not None and again.job.owner == "a1"
    # recovery sees it as any claimed job: active, and taken over once its lease is stale
    assert [j.key for j in store.active_jobs()] == ["k"]
    time.sleep(0.01)
    taken = store.claim("k", "a3", "w3", stale_after_s=0.0)
    assert taken.outcome == "claimed" and taken.job is not None and taken.job.attempts == 2
    assert "attempt 1 on w1 stopped heartbeating" in (taken.job.last_retry_reason or "")
    store.finish_with_result("k", "a3", "simulation", b'{"ok": true}')
    # the result is stored: a new request finishes the record instead of computing
    stored = store.enqueue_and_claim("k", "simulation", {"m": 1}, "a4", "w4", refresh=False)
    assert stored.outcome == "stored" and stored.job is not None
    assert (stored.job.status, stored.job.owner) == ("succeeded", None)
    # refresh: a new generation, leased, fresh attempts
    fresh = store.enqueue_and_claim("k", "simulation", {"m": 1}, "a5", "w5", refresh=True)
    assert fresh.outcome == "claimed" and fresh.job is not None
    assert (fresh.job.status, fresh.job.generation, fresh.job.attempts, fresh.job.owner) == (
        "running",
        3,
        1,
        "a5",
    )
    assert fresh.job.refresh and fresh.job.finished is None and fresh.job.error is None


def test_a_refunded_release_gives_the_attempt_back(tmp_path: Path) -> None:
    """The fast lane's hand-off (release with refund) leaves the record active and unowned
    with its reason and one attempt fewer; a plain release (a cancelled or lost attempt)
    keeps the count; only the lease holder's release does anything."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10_000, memory_cache_bytes=0)
    claim = store.enqueue_and_claim("k", "simulation", {}, "a1", "w1", refresh=False)
    assert claim.job is not None and claim.job.attempts == 1
    store.release("k", "someone-else", "not the holder", refund=True)
    job = store.get_job("k")
    assert job is not None and (job.owner, job.attempts) == ("a1", 1)
    store.release("k", "a1", "handed off", refund=True)
    job = store.get_job("k")
    assert job is not None
    assert (job.status, job.owner, job.attempts, job.last_retry_reason) == (
        "running",
        None,
        0,
        "handed off",
    )
    assert store.claim("k", "a2", "w2", stale_after_s=10.0).outcome == "claimed"
    store.release("k", "a2", "lost")
    job = store.get_job("k")
    assert job is not None and (job.owner, job.attempts) == (None, 1)


def test_reads_do_not_queue_behind_a_writer(tmp_path: Path) -> None:
    """The store's reads take no write lock (SQLite: a deferred BEGIN, reading the WAL
    snapshot): a cache lookup or a job read answers while another connection holds the
    write transaction (a cold request's lookup used to wait for the previous request's
    result write, up to the 30 s busy timeout), and reads the last committed state
    (:func:`finishes_under_write_lock`)."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10_000, memory_cache_bytes=0)
    store.put_result("a", "simulation", b'{"x":1}')
    store.enqueue_job("k", "simulation", {"x": 1})
    seen: dict[str, Any] = {}

    def read() -> None:
        seen["result"] = store.get_result("a")
        job = store.get_job("k")
        seen["job"] = job.status if job is not None else None
        seen["has"] = store.has_result("a")

    # the writer's uncommitted delete is invisible to the readers
    finished = finishes_under_write_lock(tmp_path / "db.sqlite3", read, "DELETE FROM results")
    assert finished, "a read waited for the write lock"
    assert seen == {"result": b'{"x":1}', "job": "queued", "has": True}
    store.put_result("b", "simulation", b"{}")  # writes still take the lock and commit
    assert store.get_result("b") == b"{}"
