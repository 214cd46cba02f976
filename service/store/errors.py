"""What the store raises: a refused database at start, a failed read or write later
(:class:`pipeflow.errors.StorageError`, library-level: a memo's failure is one too)."""

from __future__ import annotations

from pipeflow.errors import StorageError

__all__ = ["StorageError", "StoreRefused"]


class StoreRefused(Exception):
    """The database cannot be used as it is (damaged, empty, held by an incompatible
    server); the message says what to do.  Raised at start, never silently repaired."""
