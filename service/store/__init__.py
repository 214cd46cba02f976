"""The store: results cache and job records on SQLAlchemy 2 Core (SQLite or PostgreSQL).

One implementation for both databases and for both sides of a computation: the API
replicas (accept jobs, serve results, cancel) and the Dask tasks on the workers (claim the
job's lease, heartbeat and progress, store the result, finish the record).

Results are JSON bytes keyed by the parameter hash, stored zlib-compressed (up to 128 KiB
as they are), bounded in total stored size with least-recently-used eviction, and fronted
per replica by a bounded in-memory LRU.  A job row is written before a computation is
accepted; the attempt that computes it holds a lease (``owner`` + ``heartbeat``), so a job
whose heartbeat went stale can be taken over by any live replica, and two replicas never
compute one job at once.

Every database error surfaces as :class:`StorageError` (the service answers 503/507 and
reports not ready) and flips :attr:`Store.healthy` until a probe write succeeds again.
"""

from __future__ import annotations

import threading

from service.store.connection import PROBE_BYTES, StoreConnection, sqlite_url
from service.store.errors import StorageError, StoreRefused
from service.store.grants import GrantStore
from service.store.jobs import (
    ACTIVE,
    COST_WINDOW_S,
    STATUSES,
    Claim,
    Job,
    JobState,
    Usage,
)
from service.store.memory import MemoryLRU
from service.store.results import IDENTITY_MAX_BYTES, ZLIB_LEVEL, ResultStore

__all__ = [
    "ACTIVE",
    "COST_WINDOW_S",
    "IDENTITY_MAX_BYTES",
    "PROBE_BYTES",
    "STATUSES",
    "ZLIB_LEVEL",
    "Claim",
    "Job",
    "JobState",
    "MemoryLRU",
    "StorageError",
    "Store",
    "StoreConnection",
    "StoreRefused",
    "Usage",
    "sqlite_url",
    "worker_store",
]


class Store(ResultStore, GrantStore):
    """Thread-safe access to the database (call from threads, not the event loop): its
    results (:mod:`service.store.results`), job records (:mod:`service.store.jobs`) and
    who may follow them (:mod:`service.store.grants`) over one connection
    (:mod:`service.store.connection`)."""

    def prune_jobs(self, older_than: float) -> int:
        """The finished job records (:meth:`service.store.jobs.JobStore.prune_jobs`), then
        the grants of the records gone or reset."""
        pruned = super().prune_jobs(older_than)
        self.prune_grants()
        return pruned

    def finish_with_result(
        self, key: str, owner: str, kind: str, body: bytes, *, remember: bool = True
    ) -> bool:
        """Store the result of job ``key`` and finish its record as succeeded, in one
        transaction (what a task does when its computation ends well).  The result is
        stored even if ``owner`` no longer holds the lease (it is the result of the key
        all the same); the record is finished only if it does.  True if this call finished
        the record.  ``remember=False`` leaves the body out of the memory front (see
        :meth:`get_result`)."""
        items = {key: (kind, body)}
        packed = self.pack(items)  # before the transaction: not while holding the write lock
        with self._write() as conn:
            evicted = self._put_results(conn, packed)
            done = self._finish(conn, key, JobState.SUCCEEDED, None, owner)
        self._remember_put(items, evicted, keep=remember)
        return done


_STORES: dict[str, Store] = {}
_STORES_LOCK = threading.Lock()


def worker_store(db_url: str, cache_max_bytes: int) -> Store:
    """One store per worker process and database (no migrations: the service ran them),
    shared by the tasks (:func:`service.engine.task._store`) and by the memos their pieces carry
    (:class:`service.store.memo.StoreMemo` reopens itself here)."""
    with _STORES_LOCK:
        store = _STORES.get(db_url)
        if store is None:
            store = _STORES[db_url] = Store(db_url, cache_max_bytes, 0, migrate=False)
        return store
