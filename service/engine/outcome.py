"""What a run of a computation ends as, on the floor of the engine: the task's
:class:`Outcome` (what one run of :func:`service.engine.task.run_job` reports), and what a
request waiting for a computation gets instead of a body (the exceptions below, which the
HTTP layer turns into problems).  Imports nothing of the engine but :mod:`lifecycle`.
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from pipeflow.errors import ErrorRecord
from service.engine.lifecycle import JobState, TaskStatus

if TYPE_CHECKING:
    from service.store import Job


@dataclass(frozen=True)
class Outcome:
    """What one run of :func:`service.engine.task.run_job` reports to the replica that
    submitted it.

    ``status``: see :class:`TaskStatus` (``exception``: the task itself failed to run,
    made by the replica, :func:`result_of`); ``error``: why it failed (``failed``: as the
    job record stores it; ``storage``: the store's failure, ``data["full"]``); ``seconds``
    [s]: how long the computation ran (None when it did not); ``note``: the job's status
    (``done``, ``elsewhere``), why it stopped (``cancelled``, ``lost``) or what went wrong
    (``exception``).
    """

    status: TaskStatus
    error: ErrorRecord | None = None
    seconds: float | None = None
    note: str | None = None
    #: this run stored the result and finished the record as succeeded (in one transaction)
    finished: bool = False
    #: the result's JSON, only from a run in the API process (the fast lane) that finished
    #: the record itself: the request is answered with it, no read of the store
    body: bytes | None = None


class NoWorker(Exception):
    """No worker can take a computation now (the engine is starting, or the scheduler has
    none); answered 503 with Retry-After to a synchronous request."""


class QueueFull(Exception):
    """No room for another computation."""


class ComputationFailed(Exception):
    """The computation ended in a failure; ``error`` is what its job record says (an
    :class:`~pipeflow.errors.ErrorRecord` as JSON, see :meth:`ErrorRecord.to_dict`)."""

    def __init__(self, error: dict[str, Any]) -> None:
        record = ErrorRecord.from_dict(error)
        super().__init__(record.message if record is not None else error.get("detail", "failed"))
        self.error = error


class ComputationCancelled(Exception):
    """The computation was cancelled (DELETE on its job)."""


def internal(message: str) -> dict[str, Any]:
    """A job record's error: the engine failed (not the computation)."""
    return ErrorRecord.internal(message).to_dict()


def raise_unless_succeeded(job: Job) -> None:
    """Raise what the ended record ``job`` says, unless it succeeded (its body is then
    the stored result)."""
    match job.status:
        case JobState.SUCCEEDED:
            return
        case JobState.CANCELLED:
            raise ComputationCancelled(str((job.error or {}).get("detail", "cancelled")))
        case _:
            raise ComputationFailed(job.error or internal("failed"))


async def result_of(fut: Awaitable[Outcome]) -> Outcome:
    """The outcome ``fut`` ends with; an ``exception`` outcome when the task itself did not
    run to its end (its worker or the scheduler went away, or it raised)."""
    try:
        return await fut
    except asyncio.CancelledError:
        return Outcome(TaskStatus.EXCEPTION, note="cancelled by the scheduler (restarted or lost)")
    except Exception as exc:
        return Outcome(TaskStatus.EXCEPTION, note=f"{type(exc).__name__}: {exc}")
