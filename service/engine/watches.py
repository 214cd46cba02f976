"""Long polls: ``GET /v1/jobs/{key}?wait=`` held until the job's record ends.

No busy loop and no thread held: a wait is an event per watched key, set by
:meth:`Watches.changed` (a flight of this replica ended, a DELETE cancelled the job, or the
monitor read its record ended), after which the record is read again.  Knows nothing of
the rest of the engine: the runner and the monitor call :meth:`Watches.changed`, the
monitor reads :meth:`Watches.keys`.
"""

from __future__ import annotations

import asyncio
import contextlib
from dataclasses import dataclass, field

from service.settings import Settings
from service.store import Job, Store


@dataclass
class _Watch:
    """The long polls waiting for one job's end: set once, by :meth:`Watches.changed`."""

    ended: asyncio.Event = field(default_factory=asyncio.Event)
    waiters: int = 0


class Watches:
    """The long polls held open by this replica: ``waiting`` of them now (bounded by
    ``max_job_waiters``), grouped by the key they watch."""

    def __init__(self, settings: Settings, store: Store) -> None:
        self.settings = settings
        self.store = store
        self.by_key: dict[str, _Watch] = {}
        self.waiting = 0

    def keys(self) -> list[str]:
        """The keys watched now."""
        return list(self.by_key)

    def changed(self, key: str) -> None:
        """Wake the long polls of job ``key`` (its record may have ended)."""
        watch = self.by_key.pop(key, None)
        if watch is not None:
            watch.ended.set()

    async def wait(self, job: Job, wait_s: float) -> Job:
        """``job``'s record once it is no longer active (succeeded, failed, cancelled), or
        as it is after ``wait_s`` [s] (cut to the ``max_job_wait_s`` setting).  A spurious
        wake-up waits on for the rest of ``wait_s``.  At most ``max_job_waiters`` such
        waits at once; past it ``job`` is returned as it is.  A vanished record (pruned)
        returns the last one read."""
        wait_s = min(wait_s, self.settings.max_job_wait_s)
        if not job.active or wait_s <= 0 or self.waiting >= self.settings.max_job_waiters:
            return job
        loop = asyncio.get_running_loop()
        deadline = loop.time() + wait_s
        key = job.key
        self.waiting += 1
        try:
            while True:
                await self._until_changed(key, deadline - loop.time())
                read = await asyncio.to_thread(self.store.get_job, key)
                if read is None:
                    return job
                job = read
                if not job.active or loop.time() >= deadline:
                    return job
        finally:
            self.waiting -= 1

    async def _until_changed(self, key: str, timeout_s: float) -> None:
        watch = self.by_key.get(key)
        if watch is None:
            watch = self.by_key[key] = _Watch()
        watch.waiters += 1
        try:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(watch.ended.wait(), timeout_s)
        finally:
            watch.waiters -= 1
            if watch.waiters == 0 and self.by_key.get(key) is watch:
                del self.by_key[key]
