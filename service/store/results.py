"""The results half of the store: result bodies by key, zlib-compressed above
:data:`IDENTITY_MAX_BYTES`, bounded in total stored size (``cache_max_bytes``) with
least-recently-used eviction, and fronted per process by a bounded in-memory LRU
(``memory_cache_bytes``, :class:`MemoryLRU`).
"""

from __future__ import annotations

import contextlib
import functools
import threading
import time
import zlib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from sqlalchemy import Connection, bindparam, delete, func, select, update

from service.store.connection import StoreConnection
from service.store.errors import StorageError
from service.store.memory import MemoryLRU
from service.store.tables import results, store_stats

#: zlib level of stored results: on a 2001-sample result (125 kB of JSON) level 1 takes
#: 0.6 ms for 29.7 kB, level 6 7.2 ms for 27.4 kB (8% smaller): the compression is paid on
#: every cold request, the space only bounds the cache
ZLIB_LEVEL = 1
#: result bodies of at most this many bytes are stored as they are (codec ``identity``),
#: larger ones zlib-compressed.  Below it zlib buys disk only, at a cost paid on every cold
#: request: in-process on the 2-core machine (load ~7, interleaved, 40 rounds)
#: ``finish_with_result`` of the 125 kB LTI document (2,001 samples, 10 modes) took 1.1 ms
#: CPU stored as it is and 2.0 ms compressed (to 30 kB), and a hit read from the store
#: skips the decompression (0.3 ms).  The price is disk: up to ~4x the bytes of such a
#: result (the bound counts the stored bytes, so ``cache_max_bytes`` holds fewer such
#: results).  Larger bodies (the paper example's
#: 143 kB compresses to 61 kB; studies, 1e5 samples: megabytes) stay compressed.
IDENTITY_MAX_BYTES = 128 << 10
#: the one row of ``store_stats``
STATS_ROW = 1
#: least-recently-used rows read per eviction query (rows are deleted one by one)
EVICT_BATCH = 64

#: a result as written: (kind, the stored bytes, their codec: ``identity`` | ``zlib``)
Packed = tuple[str, bytes, str]

# a result write's statements, built once (see service.store.jobs: an inline statement is
# built and keyed on every call)
_BODY = select(results.c.body, results.c.codec).where(results.c.key == bindparam("b_key"))
_SIZES = select(results.c.key, results.c.size).where(
    results.c.key.in_(bindparam("b_keys", expanding=True))
)
_STATS = (
    select(store_stats.c.result_bytes, store_stats.c.result_rows)
    .where(store_stats.c.id == STATS_ROW)
    .with_for_update()
)
_SET_STATS = (
    update(store_stats)
    .where(store_stats.c.id == STATS_ROW)
    .values(result_bytes=bindparam("b_bytes"), result_rows=bindparam("b_rows"))
)


class ResultStore(StoreConnection):
    """Result bodies by key (see the module docstring)."""

    def __init__(
        self,
        url: str | Path,
        cache_max_bytes: int,
        memory_cache_bytes: int,
        *,
        migrate: bool = True,
        identity_max_bytes: int = IDENTITY_MAX_BYTES,
    ) -> None:
        super().__init__(url, migrate=migrate)
        self.cache_max_bytes = cache_max_bytes
        #: bodies up to this size are stored uncompressed (see :data:`IDENTITY_MAX_BYTES`)
        self.identity_max_bytes = identity_max_bytes
        self._lock = threading.Lock()
        self._memory = MemoryLRU(memory_cache_bytes)
        # memory hits not yet written to results.accessed: written before evicting
        self._touched: dict[str, float] = {}

    def close(self) -> None:
        with contextlib.suppress(StorageError), self._write() as conn:
            self._write_touched(conn)
        super().close()

    def _write_touched(self, conn: Connection) -> None:
        with self._lock:
            touched, self._touched = self._touched, {}
        if touched:  # one statement, executed for every key (executemany)
            conn.execute(
                update(results)
                .where(results.c.key == bindparam("touched_key"))
                .values(accessed=bindparam("touched_at")),
                [{"touched_key": k, "touched_at": t} for k, t in touched.items()],
            )

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
            row = conn.execute(_BODY, {"b_key": key}).first()
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
        """Store ``body`` (compressed above :attr:`identity_max_bytes`); evict
        least-recently-used results beyond the bound."""
        self.put_results({key: (kind, body)})

    def put_results(self, items: Mapping[str, tuple[str, bytes]]) -> None:
        """Store each ``key: (kind, body)`` as :meth:`pack` encodes it, in one transaction;
        then evict least-recently-used results beyond the bound (never those just
        written)."""
        if not items:
            return
        packed = self.pack(items)  # before the transaction: not while holding the write lock
        with self._write() as conn:
            evicted = self._put_results(conn, packed)
        self._remember_put(items, evicted)

    def pack(self, items: Mapping[str, tuple[str, bytes]]) -> dict[str, Packed]:
        """``key: (kind, body)`` as stored: ``key: (kind, stored bytes, codec)``, the body
        as it is up to :attr:`identity_max_bytes` (codec ``identity``), else zlib at
        :data:`ZLIB_LEVEL` (call it before the write transaction: not under the lock)."""
        limit = self.identity_max_bytes
        return {
            key: (kind, body, "identity")
            if len(body) <= limit
            else (kind, zlib.compress(body, ZLIB_LEVEL), "zlib")
            for key, (kind, body) in items.items()
        }

    def _put_results(self, conn: Connection, packed: Mapping[str, Packed]) -> list[str]:
        """:meth:`put_results` of ``packed`` (as :meth:`pack` made it) inside the
        transaction ``conn``: the evicted keys.

        The bound is checked against the running total of ``store_stats``, not a scan of
        the table.  Every write that changes the results' sizes locks that one row first
        (PostgreSQL: ``SELECT ... FOR UPDATE``; SQLite: ``BEGIN IMMEDIATE`` already
        serialises writers), so the sizes read below cannot change under this transaction
        and the total it writes back is exact, with concurrent writers in any number of
        processes and replicas; no deadlock either, as the row is always taken first."""
        now = time.time()
        total, count = self._lock_stats(conn)
        self._write_touched(conn)
        keys = list(packed)
        old = dict(conn.execute(_SIZES, {"b_keys": keys}).all())
        written: list[dict[str, Any]] = [
            {
                "key": key,
                "kind": kind,
                "body": stored,
                "size": len(stored),
                "created": now,
                "accessed": now,
                "codec": codec,
            }
            for key, (kind, stored, codec) in packed.items()
        ]
        # one upsert statement executed for every row (a study chunk's 256 summaries: one
        # compiled statement, not 256; 10,000 single upserts cost ~2-4 s on the 2 cores)
        conn.execute(self._upsert_results, written)
        for key, (_, stored, _codec) in packed.items():
            total += len(stored) - int(old.get(key, 0))
            count += 0 if key in old else 1
        evicted = []
        excess = total - self.cache_max_bytes
        while excess > 0:
            # the newest results are kept even if they alone exceed the bound; the oldest
            # rows in small batches by the index on accessed (no full scan either)
            rows = conn.execute(
                select(results.c.key, results.c.size)
                .where(results.c.key.notin_(keys))
                .order_by(results.c.accessed)
                .limit(EVICT_BATCH)
            ).all()
            if not rows:
                break
            for row in rows:
                if excess <= 0:
                    break
                conn.execute(delete(results).where(results.c.key == row.key))
                evicted.append(row.key)
                excess -= int(row.size)
                total -= int(row.size)
                count -= 1
        conn.execute(_SET_STATS, {"b_bytes": total, "b_rows": count})
        return evicted

    @functools.cached_property
    def _upsert_results(self) -> Any:
        """The upsert of result rows (every column of :meth:`_put_results`' rows)."""
        ins = self._insert(results)
        columns = ("kind", "body", "size", "created", "accessed", "codec")
        return ins.on_conflict_do_update(
            index_elements=["key"], set_={c: ins.excluded[c] for c in columns}
        )

    def _lock_stats(self, conn: Connection) -> tuple[int, int]:
        """The running totals (bytes, rows), their row locked until the end of ``conn``'s
        transaction; a missing row (a database written past the migrations' back) is
        recounted once."""
        query = _STATS
        row = conn.execute(query).first()
        if row is None:
            conn.execute(
                self._insert(store_stats)
                .values(id=STATS_ROW, result_bytes=0, result_rows=0)
                .on_conflict_do_nothing(index_elements=["id"])
            )
            row = conn.execute(query).first()
            assert row is not None
            if row.result_rows == 0:
                return self._recount(conn)
        return int(row.result_bytes), int(row.result_rows)

    def _recount(self, conn: Connection) -> tuple[int, int]:
        """Set the running totals from the table itself (a full scan: at start only)."""
        size, rows = conn.execute(
            select(func.coalesce(func.sum(results.c.size), 0), func.count()).select_from(results)
        ).one()
        conn.execute(
            update(store_stats)
            .where(store_stats.c.id == STATS_ROW)
            .values(result_bytes=int(size), result_rows=int(rows))
        )
        return int(size), int(rows)

    def recount_results(self) -> tuple[int, int]:
        """Recount the running totals from the results table (bytes, rows), under the
        totals' lock: a replica does it once at start, which also corrects any drift left
        by writers of a version before the running totals (a rolling upgrade)."""
        with self._write() as conn:
            self._lock_stats(conn)
            return self._recount(conn)

    def _remember_put(
        self, items: Mapping[str, tuple[str, bytes]], evicted: list[str], *, keep: bool = True
    ) -> None:
        """After the commit of a put: the memory front forgets the evicted keys and keeps
        the written bodies (``keep=False``: forgets them too)."""
        with self._lock:
            for old in evicted:
                self._memory.pop(old)
            for key, (_, body) in items.items():
                if keep:
                    self._memory.put(key, body)
                else:
                    self._memory.pop(key)

    def result_bytes(self) -> int:
        """Stored result bytes (the running total, O(1))."""
        with self._read() as conn:
            total = conn.execute(
                select(store_stats.c.result_bytes).where(store_stats.c.id == STATS_ROW)
            ).scalar()
        return int(total or 0)


def _decode(body: bytes, codec: str) -> bytes:
    if codec == "zlib":
        return zlib.decompress(body)
    if codec == "identity":
        return body
    raise StorageError(f"result stored with the unknown codec {codec!r}")
