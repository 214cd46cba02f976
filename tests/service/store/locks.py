"""A test helper: run a store call while another connection holds SQLite's write lock."""

from __future__ import annotations

import sqlite3
import threading
from collections.abc import Callable
from pathlib import Path


def finishes_under_write_lock(db: Path, call: Callable[[], object], *statements: str) -> bool:
    """Run ``call`` in a thread while a second connection to ``db`` holds the write lock
    (``BEGIN IMMEDIATE``, then ``statements``, uncommitted); whether it returned before the
    lock was given up.  The 20 s wait only bounds a failing run (a call that queues for the
    lock waits for the store's 30 s busy timeout); the lock is then rolled back and the
    thread joined."""
    writer = sqlite3.connect(db, isolation_level=None)
    try:
        writer.execute("BEGIN IMMEDIATE")
        for statement in statements:
            writer.execute(statement)
        worker = threading.Thread(target=call, daemon=True)
        worker.start()
        worker.join(20)
        finished = not worker.is_alive()
        writer.execute("ROLLBACK")
    finally:
        writer.close()
    worker.join(40)
    return finished
