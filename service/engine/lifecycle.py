"""The states of a job and of one run of its task: the one vocabulary of the store, the
engine and the HTTP layer (a :class:`~enum.StrEnum` is its own string: it is written to the
store's ``status`` column, compared and serialised as the plain value).

This module is the floor of the engine: it imports nothing of the service, so the store
below the engine and the HTTP layer above it may import it.
"""

from __future__ import annotations

from enum import StrEnum


class JobState(StrEnum):
    """A job record's ``status`` (the store's column, the HTTP job document)."""

    QUEUED = "queued"
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"


#: the states of a job not yet ended
ACTIVE: tuple[JobState, ...] = (JobState.QUEUED, JobState.RUNNING)
#: every state, in the order the metrics list them
STATUSES: tuple[JobState, ...] = tuple(JobState)


class TaskStatus(StrEnum):
    """How one run of a job's task ended (:class:`service.engine.outcome.Outcome`)."""

    #: it computed and stored the result (or found it stored by an earlier attempt)
    SUCCEEDED = "succeeded"
    #: the computation failed; the record says why
    FAILED = "failed"
    #: a DELETE stopped it
    CANCELLED = "cancelled"
    #: someone finished the job already: nothing to do
    DONE = "done"
    #: a live attempt holds the lease
    ELSEWHERE = "elsewhere"
    #: the fast lane found an active record there first: not claimed, the replica drives it
    QUEUED = "queued"
    #: another attempt took the lease
    LOST = "lost"
    #: the store refused a write
    STORAGE = "storage"
    #: the fast lane's metered computation would pass its allowance: left for a worker
    HANDOFF = "handoff"
    #: the fast lane looked the result up first and found it stored: nothing written
    HIT = "hit"
    #: the task itself failed to run (made by the replica, never by the task)
    EXCEPTION = "exception"


class ClaimOutcome(StrEnum):
    """What a claim of a job's lease found (:class:`service.store.Claim`)."""

    #: compute now, under the lease
    CLAIMED = "claimed"
    #: a live attempt holds the lease
    ELSEWHERE = "elsewhere"
    #: the job is finished or gone: nothing to do
    DONE = "done"
    #: its result was stored already: the claim finished the job as succeeded
    STORED = "stored"
    #: an active record was there first: not claimed (:meth:`Store.enqueue_and_claim`)
    QUEUED = "queued"
    #: the result was looked up first and found stored: nothing written
    HIT = "hit"


class LeaseState(StrEnum):
    """What a renewal of a lease found (:meth:`Store.heartbeat`)."""

    OK = "ok"
    #: stop: the job was cancelled
    CANCELLED = "cancelled"
    #: another attempt owns the job now
    LOST = "lost"


class Counted(StrEnum):
    """How a computation that a replica saw end is counted (the ``outcome`` label of the
    computations metric, :func:`service.observability.record_computation`)."""

    OK = "ok"
    ERROR = "error"
    CANCELLED = "cancelled"
