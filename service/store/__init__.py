"""The store: results cache and job records on SQLAlchemy 2 Core (SQLite or PostgreSQL).

One implementation for both databases and for both sides of a computation: the API
replicas (accept jobs, serve results, cancel) and the Dask tasks on the workers (claim the
job's lease, heartbeat and progress, store the result, finish the record).

Results are JSON bytes keyed by the parameter hash, stored zlib-compressed, bounded in
total stored size with least-recently-used eviction, and fronted per replica by a bounded
in-memory LRU.  A job row is written before a computation is accepted; the attempt that
computes it holds a lease (``owner`` + ``heartbeat``), so a job whose heartbeat went stale
can be taken over by any live replica, and two replicas never compute one job at once.

Every database error surfaces as :class:`StorageError` (the service answers 503/507 and
reports not ready) and flips :attr:`Store.healthy` until a probe write succeeds again.
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
import time
import zlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import Connection, Row, case, delete, func, select, update
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.exc import DBAPIError

from service.store.errors import StorageError, StoreRefused
from service.store.memory import MemoryLRU
from service.store.schema import check_sqlite_file, make_engine, sqlite_path, upgrade
from service.store.tables import jobs, probe, results

__all__ = [
    "ACTIVE",
    "STATUSES",
    "Claim",
    "Job",
    "MemoryLRU",
    "StorageError",
    "Store",
    "StoreRefused",
    "sqlite_url",
]

log = logging.getLogger("service.store")

ACTIVE = ("queued", "running")
STATUSES = ("queued", "running", "succeeded", "failed", "cancelled")
#: bytes the storage probe writes to decide that there is room again (a large result's worth)
PROBE_BYTES = 1 << 20


def sqlite_url(path: Path | str) -> str:
    return f"sqlite:///{Path(path)}"


#: zlib level of stored results: on a 2001-sample result (125 kB of JSON) level 1 takes
#: 0.6 ms for 29.7 kB, level 6 7.2 ms for 27.4 kB (8% smaller): the compression is paid on
#: every cold request, the space only bounds the cache
ZLIB_LEVEL = 1


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
    attempts: int = 0
    last_retry_reason: str | None = None
    refresh: bool = False
    generation: int = 1
    owner: str | None = None
    worker: str | None = None
    heartbeat: float | None = None

    @classmethod
    def from_row(cls, row: Row[Any]) -> Job:
        m = row._mapping
        return cls(
            key=m["key"],
            kind=m["kind"],
            spec=json.loads(m["spec"]),
            status=m["status"],
            progress=float(m["progress"]),
            error=json.loads(m["error"]) if m["error"] else None,
            created=m["created"],
            started=m["started"],
            finished=m["finished"],
            updated=m["updated"],
            cancel=bool(m["cancel"]),
            attempts=int(m["attempts"]),
            last_retry_reason=m["last_retry_reason"],
            refresh=bool(m["refresh"]),
            generation=int(m["generation"]),
            owner=m["owner"],
            worker=m["worker"],
            heartbeat=m["heartbeat"],
        )

    @property
    def active(self) -> bool:
        return self.status in ACTIVE


@dataclass(frozen=True)
class Claim:
    """What :meth:`Store.claim` found: ``"claimed"`` (compute now), ``"elsewhere"`` (a live
    attempt holds the lease), ``"done"`` (the job is finished or gone: nothing to do)."""

    outcome: str
    job: Job | None


def _is_full(exc: DBAPIError) -> bool:
    text = str(exc.orig).lower()
    code = getattr(exc.orig, "sqlstate", None)
    return "full" in text or "no space" in text or code == "53100"


class Store:
    """Thread-safe access to the database (call from threads, not the event loop)."""

    def __init__(
        self,
        url: str | Path,
        cache_max_bytes: int,
        memory_cache_bytes: int,
        *,
        migrate: bool = True,
    ) -> None:
        self.url = url if isinstance(url, str) else sqlite_url(url)
        self.cache_max_bytes = cache_max_bytes
        path = sqlite_path(self.url)
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            if migrate:
                check_sqlite_file(path)
        self.engine = make_engine(self.url)
        if migrate:
            upgrade(self.engine, self.url)
        self.healthy = True
        self.last_error: str | None = None
        self.last_full = False
        self._lock = threading.Lock()
        self._memory = MemoryLRU(memory_cache_bytes)
        # memory hits not yet written to results.accessed: written before evicting
        self._touched: dict[str, float] = {}

    def close(self) -> None:
        with contextlib.suppress(StorageError), self._write() as conn:
            self._write_touched(conn)
        self.engine.dispose()

    # -- error handling ----------------------------------------------------------------

    @contextlib.contextmanager
    def _guard(self) -> Iterator[None]:
        try:
            yield
        except DBAPIError as exc:
            full = _is_full(exc)
            self.healthy, self.last_full = False, full
            self.last_error = f"{type(exc.orig).__name__}: {exc.orig}"
            log.error("storage error: %s", self.last_error)
            what = "the disk of the store is full" if full else "the store failed"
            raise StorageError(f"{what} ({self.last_error})", full=full) from None

    @contextlib.contextmanager
    def _write(self) -> Iterator[Connection]:
        with self._guard(), self.engine.begin() as conn:
            yield conn

    @contextlib.contextmanager
    def _read(self) -> Iterator[Connection]:
        with self._guard(), self.engine.connect() as conn:
            yield conn

    def _insert(self, table: Any) -> Any:
        dialect = postgresql if self.engine.dialect.name == "postgresql" else sqlite
        return dialect.insert(table)

    def mark_failed(self, reason: str, *, full: bool) -> None:
        """A write elsewhere (a task on a worker) failed: unhealthy until :meth:`probe`."""
        self.healthy, self.last_error, self.last_full = False, reason, full

    def unavailable(self) -> StorageError:
        """The error to answer while unhealthy (new work would not be stored either)."""
        return StorageError(f"the store is not writable ({self.last_error})", full=self.last_full)

    def probe(self) -> bool:
        """Write and delete :data:`PROBE_BYTES`; on success the store is healthy again."""
        try:
            with self._write() as conn:
                conn.execute(delete(probe))
                conn.execute(
                    probe.insert().values(id=1, body=b"\0" * PROBE_BYTES, written=time.time())
                )
            with self._write() as conn:
                conn.execute(delete(probe))
        except StorageError:
            return False
        if not self.healthy:
            log.info("storage writable again")
        self.healthy, self.last_error = True, None
        return True

    # -- results -------------------------------------------------------------------------

    def _write_touched(self, conn: Connection) -> None:
        with self._lock:
            touched, self._touched = self._touched, {}
        for key, t in touched.items():
            conn.execute(update(results).where(results.c.key == key).values(accessed=t))

    def get_result(self, key: str, *, remember: bool = True) -> bytes | None:
        """The result body stored under ``key`` (None if absent).  ``remember=False``
        leaves the in-memory front as it is (a body read once, e.g. a fresh result sent to
        the request that computed it: its hits are answered from the app's hit cache)."""
        with self._lock:
            body = self._memory.get(key)
            if body is not None:
                self._touched[key] = time.time()
                return body
        with self._read() as conn:
            row = conn.execute(
                select(results.c.body, results.c.codec).where(results.c.key == key)
            ).first()
            if row is None:
                return None
            body = _decode(bytes(row.body), row.codec)
        with self._lock:
            self._touched[key] = time.time()
            if remember:
                self._memory.put(key, body)
        return body

    def has_result(self, key: str) -> bool:
        with self._lock:
            if self._memory.get(key) is not None:
                return True
        with self._read() as conn:
            return (
                conn.execute(select(results.c.key).where(results.c.key == key)).first() is not None
            )

    def get_results(self, keys: Sequence[str]) -> dict[str, bytes]:
        """The stored bodies among ``keys`` (one query; missing keys are absent)."""
        if not keys:
            return {}
        with self._read() as conn:
            rows = conn.execute(
                select(results.c.key, results.c.body, results.c.codec).where(
                    results.c.key.in_(list(keys))
                )
            ).all()
        found = {row.key: _decode(bytes(row.body), row.codec) for row in rows}
        now = time.time()
        with self._lock:
            self._touched.update(dict.fromkeys(found, now))
        return found

    def put_result(self, key: str, kind: str, body: bytes) -> None:
        """Store ``body`` compressed; evict least-recently-used results beyond the bound."""
        self.put_results({key: (kind, body)})

    def put_results(self, items: Mapping[str, tuple[str, bytes]]) -> None:
        """Store each ``key: (kind, body)`` compressed, in one transaction; then evict
        least-recently-used results beyond the bound (never those just written)."""
        if not items:
            return
        now = time.time()
        with self._write() as conn:
            self._write_touched(conn)
            for key, (kind, body) in items.items():
                stored = zlib.compress(body, ZLIB_LEVEL)
                values = {
                    "key": key,
                    "kind": kind,
                    "body": stored,
                    "size": len(stored),
                    "created": now,
                    "accessed": now,
                    "codec": "zlib",
                }
                ins = self._insert(results).values(**values)
                conn.execute(
                    ins.on_conflict_do_update(
                        index_elements=["key"],
                        set_={k: v for k, v in values.items() if k != "key"},
                    )
                )
            total = conn.execute(select(func.coalesce(func.sum(results.c.size), 0))).scalar_one()
            excess = int(total) - self.cache_max_bytes
            evicted = []
            if excess > 0:
                # the newest results are kept even if they alone exceed the bound
                rows = conn.execute(
                    select(results.c.key, results.c.size)
                    .where(results.c.key.notin_(list(items)))
                    .order_by(results.c.accessed)
                ).all()
                for row in rows:
                    if excess <= 0:
                        break
                    conn.execute(delete(results).where(results.c.key == row.key))
                    evicted.append(row.key)
                    excess -= int(row.size)
        with self._lock:
            for old in evicted:
                self._memory.pop(old)
            for key, (_, body) in items.items():
                self._memory.put(key, body)

    def result_bytes(self) -> int:
        with self._read() as conn:
            total = conn.execute(select(func.coalesce(func.sum(results.c.size), 0))).scalar_one()
            return int(total)

    # -- jobs (replica side) --------------------------------------------------------------

    def _job(self, conn: Connection, key: str, *, lock: bool = False) -> Job | None:
        query = select(jobs).where(jobs.c.key == key)
        row = conn.execute(query.with_for_update() if lock else query).first()
        return Job.from_row(row) if row is not None else None

    def _create_or_reset(
        self,
        conn: Connection,
        key: str,
        created: dict[str, Any],
        reset: dict[str, Any],
    ) -> None:
        """Insert job ``key`` with the ``created`` columns, or, if its row exists and is not
        active, update it with the ``reset`` columns (an active job is shared as it is)."""
        inserted = conn.execute(
            self._insert(jobs)
            .values(key=key, **created)
            .on_conflict_do_nothing(index_elements=["key"])
        ).rowcount
        if not inserted:
            conn.execute(
                update(jobs).where(jobs.c.key == key, jobs.c.status.notin_(ACTIVE)).values(**reset)
            )

    def enqueue_job(
        self, key: str, kind: str, spec: dict[str, Any], *, refresh: bool = False
    ) -> Job:
        """Create the job record, or reset a finished one to queued (a new generation);
        an active one is left as it is (identical requests share it)."""
        now = time.time()
        with self._write() as conn:
            self._create_or_reset(
                conn,
                key,
                dict(
                    kind=kind,
                    spec=json.dumps(spec),
                    status="queued",
                    progress=0.0,
                    created=now,
                    updated=now,
                    heartbeat=now,
                    refresh=refresh,
                ),
                dict(
                    kind=kind,
                    spec=json.dumps(spec),
                    status="queued",
                    progress=0.0,
                    error=None,
                    created=now,
                    started=None,
                    finished=None,
                    updated=now,
                    cancel=0,
                    attempts=0,
                    last_retry_reason=None,
                    refresh=refresh,
                    generation=jobs.c.generation + 1,
                    owner=None,
                    worker=None,
                    heartbeat=now,
                ),
            )
            job = self._job(conn, key)
        assert job is not None  # written in this transaction
        return job

    def finish_job(
        self,
        key: str,
        status: str,
        error: dict[str, Any] | None = None,
        *,
        owner: str | None = None,
    ) -> bool:
        """Move an active job to a terminal state (only if ``owner`` holds its lease, when
        given); a job already terminal is left alone.  True if this call finished it."""
        now = time.time()
        cond = [jobs.c.key == key, jobs.c.status.in_(ACTIVE)]
        if owner is not None:
            cond.append(jobs.c.owner == owner)
        with self._write() as conn:
            done = conn.execute(
                update(jobs)
                .where(*cond)
                .values(
                    status=status,
                    error=json.dumps(error) if error else None,
                    finished=now,
                    updated=now,
                    heartbeat=now,
                    owner=None,
                    progress=1.0 if status == "succeeded" else jobs.c.progress,
                )
            ).rowcount
        return bool(done)

    def mark_succeeded(self, key: str, kind: str, spec: dict[str, Any]) -> None:
        """Record a job whose result is already stored (a resubmission of a cached run)."""
        now = time.time()
        with self._write() as conn:
            self._create_or_reset(
                conn,
                key,
                dict(
                    kind=kind,
                    spec=json.dumps(spec),
                    status="succeeded",
                    progress=1.0,
                    created=now,
                    started=now,
                    finished=now,
                    updated=now,
                ),
                dict(
                    status="succeeded",
                    progress=1.0,
                    error=None,
                    finished=func.coalesce(jobs.c.finished, now),
                    updated=now,
                ),
            )

    def request_cancel(self, key: str) -> Job | None:
        """Flag an active job as cancelled (its attempt stops at its next heartbeat)."""
        now = time.time()
        with self._write() as conn:
            conn.execute(
                update(jobs)
                .where(jobs.c.key == key, jobs.c.status.in_(ACTIVE))
                .values(
                    cancel=1,
                    status="cancelled",
                    finished=now,
                    updated=now,
                    error=json.dumps({"detail": "cancelled by request"}),
                )
            )
            return self._job(conn, key)

    def get_job(self, key: str) -> Job | None:
        with self._read() as conn:
            return self._job(conn, key)

    def active_jobs(self) -> list[Job]:
        with self._read() as conn:
            rows = conn.execute(
                select(jobs).where(jobs.c.status.in_(ACTIVE)).order_by(jobs.c.created)
            ).all()
        return [Job.from_row(r) for r in rows]

    def job_counts(self) -> dict[str, int]:
        """Job records by status (every status present, zeros included)."""
        with self._read() as conn:
            rows = conn.execute(select(jobs.c.status, func.count()).group_by(jobs.c.status)).all()
        counts = {str(status): int(n) for status, n in rows}
        return {status: counts.get(status, 0) for status in STATUSES}

    def jobs_by_key(self, keys: Sequence[str]) -> dict[str, Job]:
        """The records of ``keys`` that exist (one query: the replica's monitor)."""
        if not keys:
            return {}
        with self._read() as conn:
            rows = conn.execute(select(jobs).where(jobs.c.key.in_(list(keys)))).all()
        return {job.key: job for job in map(Job.from_row, rows)}

    def stale_jobs(self, stale_after_s: float) -> list[Job]:
        """Active jobs whose owner (or submitter) has not been heard of for ``stale_after_s``."""
        limit = time.time() - stale_after_s
        with self._read() as conn:
            rows = conn.execute(
                select(jobs)
                .where(
                    jobs.c.status.in_(ACTIVE),
                    (jobs.c.heartbeat.is_(None)) | (jobs.c.heartbeat < limit),
                )
                .order_by(jobs.c.created)
            ).all()
        return [Job.from_row(r) for r in rows]

    def touch(self, keys: Sequence[str]) -> None:
        """Heartbeat of the submitter: queued jobs it still waits for are not stale."""
        if not keys:
            return
        with self._write() as conn:
            conn.execute(
                update(jobs)
                .where(jobs.c.key.in_(list(keys)), jobs.c.status == "queued")
                .values(heartbeat=time.time())
            )

    def note_retry(self, key: str, reason: str) -> None:
        """Record why an active job is being submitted again."""
        with self._write() as conn:
            conn.execute(
                update(jobs)
                .where(jobs.c.key == key, jobs.c.status.in_(ACTIVE))
                .values(last_retry_reason=reason, heartbeat=time.time())
            )

    def prune_jobs(self, older_than: float) -> int:
        """Delete finished job records whose last update is before ``older_than`` [Unix s]."""
        with self._write() as conn:
            return int(
                conn.execute(
                    delete(jobs).where(jobs.c.status.notin_(ACTIVE), jobs.c.updated < older_than)
                ).rowcount
            )

    def computations(self) -> int:
        """Total attempts ever started over the job records (tests count recomputation)."""
        with self._read() as conn:
            return int(
                conn.execute(select(func.coalesce(func.sum(jobs.c.attempts), 0))).scalar_one()
            )

    # -- jobs (task side: the attempt that computes) ---------------------------------------

    def claim(self, key: str, owner: str, worker: str, stale_after_s: float) -> Claim:
        """Take the job's lease for the attempt ``owner`` running on ``worker``.

        A lease held by another attempt whose heartbeat is younger than ``stale_after_s``
        is respected; an older one is taken over (the retry's reason says why).
        """
        now = time.time()
        with self._write() as conn:
            job = self._job(conn, key, lock=True)
            if job is None or not job.active or job.cancel:
                return Claim("done", job)
            if job.owner == owner:
                return Claim("claimed", job)
            age = now - (job.heartbeat or 0.0)
            if job.owner is not None and age < stale_after_s:
                return Claim("elsewhere", job)
            reason = job.last_retry_reason
            if job.owner is not None:
                reason = (
                    f"attempt {job.attempts} on {job.worker or 'an unknown worker'} stopped "
                    f"heartbeating ({age:.1f} s without a sign of life)"
                )
            conn.execute(
                update(jobs)
                .where(jobs.c.key == key)
                .values(
                    status="running",
                    started=now,
                    updated=now,
                    heartbeat=now,
                    progress=0.0,
                    owner=owner,
                    worker=worker,
                    attempts=jobs.c.attempts + 1,
                    last_retry_reason=reason,
                )
            )
            return Claim("claimed", self._job(conn, key))

    def heartbeat(self, key: str, owner: str, progress: float | None = None) -> str:
        """Renew the lease (and record ``progress`` in [0, 1]): ``"ok"``, ``"cancelled"``
        (stop: the job was cancelled) or ``"lost"`` (another attempt owns the job now)."""
        now = time.time()
        values: dict[str, Any] = {"heartbeat": now, "updated": now}
        if progress is not None:
            p = min(max(progress, 0.0), 1.0)
            values["progress"] = case((jobs.c.progress < p, p), else_=jobs.c.progress)
        with self._write() as conn:
            renewed = conn.execute(
                update(jobs)
                .where(
                    jobs.c.key == key,
                    jobs.c.owner == owner,
                    jobs.c.status == "running",
                    jobs.c.cancel == 0,
                )
                .values(**values)
            ).rowcount
            if renewed:
                return "ok"
            job = self._job(conn, key)
        if job is not None and (job.cancel or job.status == "cancelled"):
            return "cancelled"
        return "lost"

    def release(self, key: str, owner: str, reason: str | None = None) -> None:
        """Give up the lease without finishing (the job is retried; ``reason`` says why)."""
        with self._write() as conn:
            values: dict[str, Any] = {"owner": None, "heartbeat": time.time()}
            if reason is not None:
                values["last_retry_reason"] = reason
            conn.execute(
                update(jobs).where(jobs.c.key == key, jobs.c.owner == owner).values(**values)
            )


def _decode(body: bytes, codec: str) -> bytes:
    if codec == "zlib":
        return zlib.decompress(body)
    if codec == "identity":
        return body
    raise StorageError(f"result stored with the unknown codec {codec!r}")
