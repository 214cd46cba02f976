"""The embedded store: results cache and job records in one SQLite file (WAL mode).

Only the standard library is imported here, so worker processes can open the store to
record progress without pulling in numpy before their BLAS threads are pinned.

Results are JSON bytes keyed by the parameter hash, bounded in total size on disk with
least-recently-used eviction, and fronted by a bounded in-memory LRU.  Job records are
written when a computation is accepted, so a restarted server can pick up what was
queued or running when the previous one died.
"""

from __future__ import annotations

import json
import sqlite3
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ACTIVE = ("queued", "running")
STATUSES = ("queued", "running", "succeeded", "failed", "cancelled")

_SCHEMA = """
CREATE TABLE IF NOT EXISTS results (
    key TEXT PRIMARY KEY,
    kind TEXT NOT NULL,
    body BLOB NOT NULL,
    size INTEGER NOT NULL,
    created REAL NOT NULL,
    accessed REAL NOT NULL
);
CREATE INDEX IF NOT EXISTS results_accessed ON results (accessed);
CREATE TABLE IF NOT EXISTS jobs (
    key TEXT PRIMARY KEY,
    kind TEXT NOT NULL,
    spec TEXT NOT NULL,
    status TEXT NOT NULL,
    progress REAL NOT NULL DEFAULT 0,
    error TEXT,
    created REAL NOT NULL,
    started REAL,
    finished REAL,
    updated REAL NOT NULL,
    cancel INTEGER NOT NULL DEFAULT 0
);
CREATE INDEX IF NOT EXISTS jobs_status ON jobs (status);
"""


def connect(path: Path | str) -> sqlite3.Connection:
    """Open the store in autocommit mode with WAL journaling and a generous busy timeout."""
    conn = sqlite3.connect(str(path), timeout=30.0, isolation_level=None, check_same_thread=False)
    conn.row_factory = sqlite3.Row
    conn.execute("PRAGMA journal_mode=WAL")
    conn.execute("PRAGMA synchronous=NORMAL")  # durable across process crashes, not power loss
    conn.execute("PRAGMA busy_timeout=30000")
    return conn


@dataclass(frozen=True)
class Job:
    """One job record; times are Unix seconds (UTC)."""

    key: str
    kind: str
    spec: dict[str, Any]
    status: str
    progress: float
    error: dict[str, Any] | None
    created: float
    started: float | None
    finished: float | None
    updated: float
    cancel: bool

    @classmethod
    def from_row(cls, row: sqlite3.Row) -> Job:
        return cls(
            key=row["key"],
            kind=row["kind"],
            spec=json.loads(row["spec"]),
            status=row["status"],
            progress=float(row["progress"]),
            error=json.loads(row["error"]) if row["error"] else None,
            created=row["created"],
            started=row["started"],
            finished=row["finished"],
            updated=row["updated"],
            cancel=bool(row["cancel"]),
        )


class _MemoryLRU:
    """Bytes values bounded by their total length."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = max_bytes
        self._items: OrderedDict[str, bytes] = OrderedDict()
        self._size = 0

    def get(self, key: str) -> bytes | None:
        value = self._items.get(key)
        if value is not None:
            self._items.move_to_end(key)
        return value

    def put(self, key: str, value: bytes) -> None:
        self.pop(key)
        if len(value) > self.max_bytes:
            return
        self._items[key] = value
        self._size += len(value)
        while self._size > self.max_bytes:
            _, old = self._items.popitem(last=False)
            self._size -= len(old)

    def pop(self, key: str) -> None:
        old = self._items.pop(key, None)
        if old is not None:
            self._size -= len(old)


class Store:
    """Thread-safe access to the SQLite file for the server process (call from threads)."""

    def __init__(self, path: Path, cache_max_bytes: int, memory_cache_bytes: int) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.cache_max_bytes = cache_max_bytes
        self._conn = connect(path)
        self._conn.executescript(_SCHEMA)
        self._lock = threading.Lock()
        self._memory = _MemoryLRU(memory_cache_bytes)
        # memory hits not yet written to results.accessed: written before evicting
        self._touched: dict[str, float] = {}

    def close(self) -> None:
        with self._lock:
            self._write_touched()
            self._conn.close()

    def _write_touched(self) -> None:
        """Record the memory front's hits in ``accessed`` (one statement, under the lock)."""
        if self._touched:
            self._conn.executemany(
                "UPDATE results SET accessed = ? WHERE key = ?",
                [(t, k) for k, t in self._touched.items()],
            )
            self._touched.clear()

    # -- results -------------------------------------------------------------------------

    def get_result(self, key: str) -> bytes | None:
        with self._lock:
            body = self._memory.get(key)
            if body is not None:
                self._touched[key] = time.time()
                return body
            row = self._conn.execute("SELECT body FROM results WHERE key = ?", (key,)).fetchone()
            if row is None:
                return None
            body = bytes(row["body"])
            self._conn.execute("UPDATE results SET accessed = ? WHERE key = ?", (time.time(), key))
            self._memory.put(key, body)
            return body

    def has_result(self, key: str) -> bool:
        with self._lock:
            if self._memory.get(key) is not None:
                return True
            row = self._conn.execute("SELECT 1 FROM results WHERE key = ?", (key,)).fetchone()
            return row is not None

    def put_result(self, key: str, kind: str, body: bytes) -> None:
        """Store ``body`` and evict least-recently-used results beyond the size bound."""
        now = time.time()
        with self._lock:
            self._conn.execute("BEGIN IMMEDIATE")
            try:
                self._write_touched()
                self._conn.execute(
                    "INSERT OR REPLACE INTO results (key, kind, body, size, created, accessed) "
                    "VALUES (?, ?, ?, ?, ?, ?)",
                    (key, kind, body, len(body), now, now),
                )
                total = self._conn.execute("SELECT COALESCE(SUM(size), 0) FROM results").fetchone()
                excess = int(total[0]) - self.cache_max_bytes
                if excess > 0:
                    # the newest result is kept even if it alone exceeds the bound
                    rows = self._conn.execute(
                        "SELECT key, size FROM results WHERE key != ? ORDER BY accessed",
                        (key,),
                    ).fetchall()
                    for row in rows:
                        if excess <= 0:
                            break
                        self._conn.execute("DELETE FROM results WHERE key = ?", (row["key"],))
                        self._memory.pop(row["key"])
                        excess -= int(row["size"])
                self._conn.execute("COMMIT")
            except BaseException:
                self._conn.execute("ROLLBACK")
                raise
            self._memory.put(key, body)

    def result_bytes(self) -> int:
        with self._lock:
            row = self._conn.execute("SELECT COALESCE(SUM(size), 0) FROM results").fetchone()
            return int(row[0])

    # -- jobs ----------------------------------------------------------------------------

    def enqueue_job(self, key: str, kind: str, spec: dict[str, Any]) -> None:
        """Create the job record, or reset a finished one to queued (keeps an active one's age)."""
        now = time.time()
        with self._lock:
            self._conn.execute(
                "INSERT INTO jobs (key, kind, spec, status, progress, created, updated) "
                "VALUES (?, ?, ?, 'queued', 0, ?, ?) "
                "ON CONFLICT(key) DO UPDATE SET kind = excluded.kind, spec = excluded.spec, "
                "status = 'queued', progress = 0, error = NULL, started = NULL, "
                "finished = NULL, cancel = 0, updated = excluded.updated, "
                "created = CASE WHEN jobs.status IN ('queued', 'running') "
                "THEN jobs.created ELSE excluded.created END",
                (key, kind, json.dumps(spec), now, now),
            )

    def finish_job(self, key: str, status: str, error: dict[str, Any] | None = None) -> None:
        """Move an active job to a terminal state; a job already terminal is left alone."""
        now = time.time()
        with self._lock:
            self._conn.execute(
                "UPDATE jobs SET status = ?, error = ?, finished = ?, updated = ?, "
                "progress = CASE WHEN ? = 'succeeded' THEN 1 ELSE progress END "
                "WHERE key = ? AND status IN ('queued', 'running')",
                (status, json.dumps(error) if error else None, now, now, status, key),
            )

    def mark_succeeded(self, key: str, kind: str, spec: dict[str, Any]) -> None:
        """Record a job whose result is already stored (a resubmission of a cached run)."""
        now = time.time()
        with self._lock:
            self._conn.execute(
                "INSERT INTO jobs (key, kind, spec, status, progress, created, started, "
                "finished, updated) VALUES (?, ?, ?, 'succeeded', 1, ?, ?, ?, ?) "
                "ON CONFLICT(key) DO UPDATE SET status = 'succeeded', progress = 1, "
                "error = NULL, finished = COALESCE(jobs.finished, excluded.finished), "
                "updated = excluded.updated WHERE jobs.status NOT IN ('queued', 'running')",
                (key, kind, json.dumps(spec), now, now, now, now),
            )

    def request_cancel(self, key: str) -> Job | None:
        """Flag an active job as cancelled (the worker stops at its next progress check)."""
        now = time.time()
        with self._lock:
            self._conn.execute(
                "UPDATE jobs SET cancel = 1, status = 'cancelled', finished = ?, updated = ?, "
                "error = ? WHERE key = ? AND status IN ('queued', 'running')",
                (now, now, json.dumps({"detail": "cancelled by request"}), key),
            )
            row = self._conn.execute("SELECT * FROM jobs WHERE key = ?", (key,)).fetchone()
        return Job.from_row(row) if row else None

    def get_job(self, key: str) -> Job | None:
        with self._lock:
            row = self._conn.execute("SELECT * FROM jobs WHERE key = ?", (key,)).fetchone()
        return Job.from_row(row) if row else None

    def active_jobs(self) -> list[Job]:
        with self._lock:
            rows = self._conn.execute(
                "SELECT * FROM jobs WHERE status IN ('queued', 'running') ORDER BY created"
            ).fetchall()
        return [Job.from_row(r) for r in rows]

    def job_counts(self) -> dict[str, int]:
        """Job records by status (every status present, zeros included)."""
        with self._lock:
            rows = self._conn.execute("SELECT status, COUNT(*) FROM jobs GROUP BY status")
            counts = {str(status): int(n) for status, n in rows.fetchall()}
        return {status: counts.get(status, 0) for status in STATUSES}

    def prune_jobs(self, older_than: float) -> int:
        """Delete finished job records whose last update is before ``older_than`` [Unix s]."""
        with self._lock:
            cur = self._conn.execute(
                "DELETE FROM jobs WHERE status NOT IN ('queued', 'running') AND updated < ?",
                (older_than,),
            )
            return cur.rowcount


# -- worker side: a worker process owns its own connection ----------------------------------


def mark_started(conn: sqlite3.Connection, key: str) -> bool:
    """Mark the job running (a new attempt starts its clock); False if it was cancelled."""
    now = time.time()
    conn.execute(
        "UPDATE jobs SET status = 'running', started = ?, updated = ?, progress = 0 "
        "WHERE key = ? AND status IN ('queued', 'running') AND cancel = 0",
        (now, now, key),
    )
    row = conn.execute("SELECT cancel FROM jobs WHERE key = ?", (key,)).fetchone()
    return not (row is not None and row["cancel"])


def report_progress(conn: sqlite3.Connection, key: str, fraction: float) -> bool:
    """Record progress in [0, 1]; returns True when the job has been cancelled."""
    conn.execute(
        "UPDATE jobs SET progress = MAX(progress, ?), updated = ? "
        "WHERE key = ? AND status = 'running'",
        (min(max(fraction, 0.0), 1.0), time.time(), key),
    )
    row = conn.execute("SELECT cancel FROM jobs WHERE key = ?", (key,)).fetchone()
    return row is not None and bool(row["cancel"])
