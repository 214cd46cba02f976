"""What the store raises: a refused database at start, a failed read or write later."""

from __future__ import annotations


class StoreRefused(Exception):
    """The database cannot be used as it is (damaged, empty, held by an incompatible
    server); the message says what to do.  Raised at start, never silently repaired."""


class StorageError(Exception):
    """A read or write of the store failed (disk full, I/O error, database unreachable).

    ``full`` is True when the cause is lack of space (answered 507, else 503); the service
    retries by itself, so the client is told to come back (``Retry-After``).
    """

    def __init__(self, message: str, *, full: bool = False) -> None:
        super().__init__(message)
        self.full = full
