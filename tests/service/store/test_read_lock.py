"""Reads of the SQLite store take no write lock (service.store.schema.READ_ONLY).

Every read used to begin with ``BEGIN IMMEDIATE``, the write lock: a job's polls
(``GET /v1/jobs/{key}``, ~50 a second from a polling client) and the study pieces' memo
look-ups queued the workers' writes (memo rows, heartbeats) behind them, and each queued
writer slept SQLite's busy-handler back-off (1, 2, 5, 10 ms, ...).  In WAL mode a deferred
transaction reads its snapshot while another connection holds the write lock, so a read
must answer while a writer (here another connection, as another process would) holds it.
"""

from __future__ import annotations

import sqlite3
import threading
from pathlib import Path
from typing import Any

from service.store import Store


def test_reads_answer_while_another_connection_holds_the_write_lock(tmp_path: Path) -> None:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=1 << 20, memory_cache_bytes=0)
    store.put_result("k", "simulation", b'{"a": 1}')
    holder = sqlite3.connect(tmp_path / "db.sqlite3", isolation_level=None)
    holder.execute("BEGIN IMMEDIATE")  # a writer elsewhere holds the write lock
    done: list[Any] = []
    try:
        reader = threading.Thread(
            target=lambda: done.append((store.get_job("nope"), store.get_results(["k"]))),
            daemon=True,
        )
        reader.start()
        # a read that waits for the lock would wait the 30 s busy timeout: a hang, not a
        # speed, is what this bound detects
        reader.join(10.0)
        assert done == [(None, {"k": b'{"a": 1}'})]
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    # writes still take the lock at BEGIN and succeed once it is free
    store.put_result("k2", "simulation", b"{}")
    assert store.get_results(["k2"]) == {"k2": b"{}"}
