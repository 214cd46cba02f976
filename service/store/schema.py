"""Opening the database: the engine, the integrity check and the migrations (at start).

One code path for SQLite (the default, a WAL-mode file in ``PIPEFLOW_DATA_DIR``) and
PostgreSQL (``postgresql+psycopg://...``).  SQLite writes take the write lock at ``BEGIN``
(``BEGIN IMMEDIATE``), so concurrent writers queue on the busy timeout instead of failing
to upgrade a read lock; a connection marked :data:`READ_ONLY` (the store's reads) begins a
deferred transaction instead: in WAL mode it reads its snapshot while a writer holds the
lock, rather than queueing behind every writer (a cold request's cache lookup used to wait
for the previous request's result write).
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from sqlalchemy import Engine, create_engine, event, inspect, text
from sqlalchemy.engine import make_url
from sqlalchemy.exc import DBAPIError

from service.store.errors import StoreRefused

log = logging.getLogger("service.store")

MIGRATIONS = Path(__file__).with_name("migrations")
#: PostgreSQL advisory lock id held while migrating (replicas starting together)
MIGRATION_LOCK = 0x70697065


def sqlite_path(url: str) -> Path | None:
    """The file of a ``sqlite:///`` URL (None for other databases or in-memory SQLite)."""
    parsed = make_url(url)
    if parsed.get_backend_name() != "sqlite" or parsed.database in (None, "", ":memory:"):
        return None
    return Path(parsed.database)


#: execution option of a connection that only reads (SQLite: ``BEGIN``, not ``BEGIN
#: IMMEDIATE``; see :func:`make_engine`)
READ_ONLY = "pipeflow_read_only"


def make_engine(url: str) -> Engine:
    """An engine for ``url``; SQLite gets WAL, a 30 s busy timeout and BEGIN IMMEDIATE
    (a plain, deferred BEGIN on a connection with the :data:`READ_ONLY` execution option,
    which must then only read: a deferred transaction that writes could fail to upgrade)."""
    if make_url(url).get_backend_name() != "sqlite":
        return create_engine(url, pool_pre_ping=True, pool_size=5, max_overflow=10)
    engine = create_engine(
        url, connect_args={"timeout": 30.0, "check_same_thread": False, "isolation_level": None}
    )

    @event.listens_for(engine, "connect")
    def _pragmas(dbapi_conn: sqlite3.Connection, _: Any) -> None:
        dbapi_conn.execute("PRAGMA journal_mode=WAL")
        dbapi_conn.execute("PRAGMA synchronous=NORMAL")  # durable across process crashes
        dbapi_conn.execute("PRAGMA busy_timeout=30000")

    @event.listens_for(engine, "begin")
    def _begin(conn: Any) -> None:
        read_only = conn.get_execution_options().get(READ_ONLY, False)
        conn.exec_driver_sql("BEGIN" if read_only else "BEGIN IMMEDIATE")

    return engine


def check_sqlite_file(path: Path) -> None:
    """Refuse an empty or damaged SQLite file with a message that says what to do."""
    if not path.exists():
        return
    if path.stat().st_size == 0:
        raise StoreRefused(
            f"{path} is empty (0 bytes) where the pipeflow database was expected: its data is "
            "gone (truncated by a crash, a full disk or a copy). Restore it from a backup, or "
            "move the file away to start with an empty store; it is not reinitialised "
            "silently."
        )
    advice = (
        f"Restore {path} from a backup, or salvage it with "
        f"`sqlite3 {path} .recover | sqlite3 {path}.recovered` and put the recovered file in "
        "its place, or move it away to start with an empty store."
    )
    try:
        conn = sqlite3.connect(f"file:{path}?mode=ro", uri=True, timeout=30.0)
        try:
            rows = [r[0] for r in conn.execute("PRAGMA quick_check(5)").fetchall()]
        finally:
            conn.close()
    except sqlite3.DatabaseError as exc:
        raise StoreRefused(f"{path} is not a readable SQLite database ({exc}). {advice}") from exc
    if rows != ["ok"]:
        raise StoreRefused(f"{path} is damaged (PRAGMA quick_check: {'; '.join(rows)}). {advice}")


@contextlib.contextmanager
def _migration_lock(engine: Engine, url: str) -> Iterator[Any]:
    """Serialise migrations of replicas starting together on one database."""
    path = sqlite_path(url)
    if path is not None:
        with open(path.with_name(path.name + ".migrate.lock"), "a+") as fh:
            fcntl.flock(fh, fcntl.LOCK_EX)
            try:
                with engine.connect() as conn:
                    yield conn
            finally:
                fcntl.flock(fh, fcntl.LOCK_UN)
        return
    with engine.connect() as conn:
        if engine.dialect.name == "postgresql":
            conn.execute(text("SELECT pg_advisory_lock(:id)"), {"id": MIGRATION_LOCK})
            conn.commit()
        try:
            yield conn
        finally:
            if engine.dialect.name == "postgresql":
                conn.execute(text("SELECT pg_advisory_unlock(:id)"), {"id": MIGRATION_LOCK})
                conn.commit()


def upgrade(engine: Engine, url: str) -> None:
    """Bring the database to the newest schema (alembic ``upgrade head``).

    A database written by the pre-alembic store (tables but no ``alembic_version``) is
    stamped as revision 0001 first, so its data is kept and migrated.
    """
    # imported here: alembic is ~10 MB in every process, and only the API process migrates
    # (the workers open the store without migrations)
    from alembic import command
    from alembic.config import Config

    try:
        with _migration_lock(engine, url) as conn:
            cfg = Config()
            cfg.set_main_option("script_location", str(MIGRATIONS))
            cfg.attributes["connection"] = conn
            tables = set(inspect(conn).get_table_names())
            if "jobs" in tables and "alembic_version" not in tables:
                log.info("stamping a pre-alembic store as revision 0001")
                command.stamp(cfg, "0001")
            command.upgrade(cfg, "head")
            conn.commit()
    except DBAPIError as exc:
        raise StoreRefused(
            f"the database at {make_url(url).render_as_string(hide_password=True)} could not be "
            f"opened or migrated ({exc.orig}). Check that it is reachable and writable."
        ) from exc
