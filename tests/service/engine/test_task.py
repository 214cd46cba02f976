"""The task's lease keeping (:mod:`service.engine.task`): one heartbeat thread per process
for all the leases its computations hold, each renewed at its own interval."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from service.engine.task import Accept, TaskConfig, run_job
from service.store import Claim, StorageError, Store
from tests.service.kinds_for_tests import SLEEP, SleepSpec


def _cfg(store: Store, interval: float = 0.02) -> TaskConfig:
    return TaskConfig(
        db_url=store.url,
        cache_max_bytes=store.cache_max_bytes,
        timeout_s=30.0,
        progress_interval_s=interval,
        stale_after_s=10.0,
        grace_s=5.0,
    )


def _heartbeat_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "heartbeats" or "heartbeat-" in t.name]


def test_one_heartbeat_thread_renews_every_lease_of_the_process(tmp_path: Path) -> None:
    """Four computations at once in threads of one process (the fast lane's shape), each
    holding its lease for 0.4 s at a 0.02 s interval: one heartbeat thread renews all four
    (the record's heartbeat moves while they run), and no thread is started per
    computation (before: one ``heartbeat-<key>`` thread each)."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**7, memory_cache_bytes=0)
    cfg = _cfg(store)
    keys = [f"k{i}" for i in range(4)]
    for key in keys:
        store.enqueue_job(key, SLEEP.name, {})
    seen: dict[str, set[float]] = {key: set() for key in keys}
    threads_seen: set[int] = set()
    done = threading.Event()

    def watch() -> None:  # the records' heartbeats while the computations run
        while not done.is_set():
            for key, job in store.jobs_by_key(keys).items():
                if job.status == "running" and job.heartbeat is not None:
                    seen[key].add(job.heartbeat)
            threads_seen.update(id(t) for t in _heartbeat_threads())
            time.sleep(0.01)

    watcher = threading.Thread(target=watch)
    watcher.start()
    try:
        with ThreadPoolExecutor(4) as pool:
            outcomes = list(
                pool.map(
                    lambda key: run_job(
                        SLEEP, SleepSpec(seconds=0.4, tag=key), key, cfg, None, store
                    ),
                    keys,
                )
            )
    finally:
        done.set()
        watcher.join()
    assert [o.status for o in outcomes] == ["succeeded"] * 4, outcomes
    # 0.4 s at 0.02 s: ~20 renewals each; at least a few seen per record (loaded machine)
    assert all(len(beats) >= 3 for beats in seen.values()), {k: len(v) for k, v in seen.items()}
    assert len(threads_seen) == 1  # one thread, the same for all four
    assert all(store.get_job(k).status == "succeeded" for k in keys)  # type: ignore[union-attr]


def test_a_cancel_reaches_the_computation_through_the_shared_heartbeat(tmp_path: Path) -> None:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**7, memory_cache_bytes=0)
    store.enqueue_job("c", SLEEP.name, {})
    threading.Timer(0.2, store.request_cancel, args=("c",)).start()
    started = time.monotonic()
    outcome = run_job(SLEEP, SleepSpec(seconds=20.0), "c", _cfg(store), None, store)
    assert outcome.status == "cancelled" and time.monotonic() - started < 10


def test_accept_writes_the_record_and_reports_the_claim(tmp_path: Path) -> None:
    """``run_job(accept=...)`` (the lane's first attempt) writes the record leased to
    itself and calls back with the claim before computing; a refused write calls back
    with the StorageError and the outcome is ``storage``."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**7, memory_cache_bytes=0)
    got: list[Claim | StorageError] = []
    accept = Accept({"seconds": 0.01}, False, got.append)
    outcome = run_job(SLEEP, SleepSpec(seconds=0.01), "a", _cfg(store), None, store, accept)
    assert outcome.status == "succeeded" and outcome.finished and outcome.body is not None
    assert len(got) == 1 and isinstance(got[0], Claim) and got[0].outcome == "claimed"
    assert got[0].job is not None and got[0].job.status == "running"
    job = store.get_job("a")
    assert job is not None and (job.status, job.attempts, job.owner) == ("succeeded", 1, None)

    store.engine.dispose()
    (tmp_path / "db.sqlite3").unlink()
    (tmp_path / "db.sqlite3").mkdir()  # the file is now a directory: every write fails
    got.clear()
    outcome = run_job(SLEEP, SleepSpec(seconds=0.01), "b", _cfg(store), None, store, accept)
    assert outcome.status == "storage"
    assert len(got) == 1 and isinstance(got[0], StorageError)


def test_a_look_up_attempt_answers_a_stored_result_without_writing(tmp_path: Path) -> None:
    """``Accept(look_up=True)`` (a cold request's lookup in the lane's thread): a stored
    result is the outcome ``hit`` with its body, the claim callback gets a ``hit`` claim,
    and no record is written; a miss goes on as an ordinary accepted attempt."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**7, memory_cache_bytes=0)
    store.put_result("stored", "sleep", b'{"slept":0.01}')
    got: list[Claim | StorageError] = []
    accept = Accept({"seconds": 0.01}, False, got.append, look_up=True)
    outcome = run_job(SLEEP, SleepSpec(seconds=0.01), "stored", _cfg(store), None, store, accept)
    assert outcome.status == "hit" and outcome.body == b'{"slept":0.01}'
    assert len(got) == 1 and isinstance(got[0], Claim) and got[0].outcome == "hit"
    assert store.get_job("stored") is None
    got.clear()
    outcome = run_job(SLEEP, SleepSpec(seconds=0.01), "new", _cfg(store), None, store, accept)
    assert outcome.status == "succeeded" and outcome.finished and outcome.body is not None
    assert isinstance(got[0], Claim) and got[0].outcome == "claimed"
    job = store.get_job("new")
    assert job is not None and (job.status, job.attempts) == ("succeeded", 1)
