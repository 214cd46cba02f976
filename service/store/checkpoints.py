"""The service's :class:`pipeflow.solvers.checkpoint.Checkpoints`: one attempt's
checkpoints as a row of the store's ``checkpoints`` table (job key + generation).

The task of a job (:func:`service.engine.task.run_job`) installs one for its computation;
a solve that runs long enough saves its progress there every ``interval_s``, and the next
attempt at the same generation of the job (after its worker or server was killed) finds it
and resumes.  A failing store does not fail the computation: a failed read is no
checkpoint, a failed write is logged (the previous checkpoint stays valid), and a write
from an attempt that lost its lease is dropped (:meth:`JobStore.save_checkpoint`).
"""

from __future__ import annotations

import logging

from service.store import StorageError, Store

log = logging.getLogger("service.store")


class StoreCheckpoints:
    """Checkpoints of the attempt ``owner`` at generation ``generation`` of job ``key``.

    ``interval_s`` [s] and ``max_bytes`` [bytes] are the service's settings
    (``checkpoint_interval_s``, ``checkpoint_max_bytes``); ``resumable``: an earlier
    attempt at this generation may have left one (else :meth:`load` reads nothing: the
    first attempt of a cold request pays no query).  :meth:`load` reads the store
    once per attempt (the checkpoint left by an earlier attempt), however many solves of
    the computation ask (a study's cases run here each ask), and returns it until this
    attempt saves its own.
    """

    def __init__(
        self,
        store: Store,
        key: str,
        generation: int,
        owner: str,
        interval_s: float,
        max_bytes: int,
        resumable: bool = True,
    ) -> None:
        self.store, self.key, self.generation, self.owner = store, key, generation, owner
        self.interval_s = interval_s
        self.max_bytes = max_bytes
        # a job's first attempt at a generation cannot find a checkpoint: no read
        self._read = not resumable
        self._blob: bytes | None = None
        self.saved = 0  # checkpoints written by this attempt

    def load(self) -> bytes | None:
        if not self._read:
            self._read = True
            try:
                self._blob = self.store.load_checkpoint(self.key, self.generation)
            except StorageError as exc:
                log.warning("checkpoint of job %s not read, from zero: %s", self.key, exc)
        return self._blob

    def save(self, data: bytes) -> None:
        self._read, self._blob = True, None  # superseded (and not kept in memory)
        try:
            if self.store.save_checkpoint(self.key, self.generation, self.owner, data):
                self.saved += 1
        except StorageError as exc:
            log.warning("checkpoint of job %s not written: %s", self.key, exc)
