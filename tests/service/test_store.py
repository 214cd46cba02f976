"""The SQLite store: persistence, bounded size with LRU eviction, the memory front."""

from __future__ import annotations

from pathlib import Path

from service.store import Store, _MemoryLRU


def test_results_survive_reopening(tmp_path: Path) -> None:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10_000, memory_cache_bytes=1000)
    store.put_result("a", "simulation", b'{"x":1}')
    store.close()
    again = Store(tmp_path / "db.sqlite3", cache_max_bytes=10_000, memory_cache_bytes=1000)
    assert again.get_result("a") == b'{"x":1}'
    assert again.get_result("b") is None


def test_disk_bound_evicts_least_recently_used(tmp_path: Path) -> None:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=250, memory_cache_bytes=0)
    for key in "abc":
        store.put_result(key, "simulation", b"{" + b" " * 98 + b"}")  # 100 bytes each
    assert store.result_bytes() <= 250
    assert store.get_result("a") is None  # oldest went first
    assert store.get_result("c") is not None
    store.get_result("b")  # b is now more recent than c
    store.put_result("d", "simulation", b"{" + b" " * 98 + b"}")
    assert store.get_result("c") is None
    assert store.get_result("b") is not None and store.get_result("d") is not None


def test_memory_hits_count_for_disk_eviction(tmp_path: Path) -> None:
    """A result served from the memory front is recently used on disk too: the disk
    bound evicts the result nobody asked for, not the hot one."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=250, memory_cache_bytes=1000)
    body = b"{" + b" " * 98 + b"}"  # 100 bytes
    store.put_result("a", "simulation", body)
    store.put_result("b", "simulation", body)
    assert store.get_result("a") == body  # a memory hit: a is now more recent than b
    store.put_result("c", "simulation", body)
    assert store.get_result("b") is None
    assert store.get_result("a") == body and store.get_result("c") == body


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
