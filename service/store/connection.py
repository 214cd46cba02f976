"""The store's connection: the database engine (SQLite or PostgreSQL), migrations at
start, transactions, and the health of the store.

Every database error surfaces as :class:`StorageError` (the service answers 503/507 and
reports not ready) and flips :attr:`StoreConnection.healthy` until a probe write succeeds
again (:meth:`StoreConnection.probe`).
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from sqlalchemy import Connection, delete
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.exc import DBAPIError

from service.store.errors import StorageError
from service.store.schema import READ_ONLY, check_sqlite_file, make_engine, sqlite_path, upgrade
from service.store.tables import probe

log = logging.getLogger("service.store")

#: bytes the storage probe writes to decide that there is room again (a large result's worth)
PROBE_BYTES = 1 << 20


def sqlite_url(path: Path | str) -> str:
    return f"sqlite:///{Path(path)}"


def _is_full(exc: DBAPIError) -> bool:
    text = str(exc.orig).lower()
    code = getattr(exc.orig, "sqlstate", None)
    return "full" in text or "no space" in text or code == "53100"


class StoreConnection:
    """The database behind a store, its transactions and its health (call from threads,
    not the event loop)."""

    def __init__(self, url: str | Path, *, migrate: bool = True) -> None:
        self.url = url if isinstance(url, str) else sqlite_url(url)
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

    def close(self) -> None:
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
        """A connection that only reads (SQLite: a deferred transaction, which does not
        wait for the write lock; see :func:`service.store.schema.make_engine`)."""
        with self._guard(), self.engine.connect() as conn:
            conn.execution_options(**{READ_ONLY: True})
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
