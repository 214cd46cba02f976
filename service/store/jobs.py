"""The jobs half of the store: one record per job key, written before a computation is
accepted (replica side), whose lease (``owner`` + ``heartbeat``) the attempt computing it
holds (task side), so a job whose heartbeat went stale can be taken over by any live
replica, and two replicas never compute one job at once.

The records are also the durable job queue (issue 22, defect 4): an asynchronous job is
accepted as a ``queued`` record without a ``dispatcher`` (:meth:`JobStore.queue_job`, up to
a bound), and a replica with a free worker takes the next ones
(:meth:`JobStore.claim_waiting`: in order within a client, fairly between clients, one
conditional UPDATE per job so two replicas never take the same one).  A record says who
asked for it (``principal``) and its estimated cost, which the per-client quotas count
(:meth:`JobStore.usage`).
"""

from __future__ import annotations

import functools
import json
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from sqlalchemy import Connection, Row, bindparam, case, delete, func, select, update

from service.engine.lifecycle import ACTIVE, STATUSES, ClaimOutcome, JobState, LeaseState
from service.store.connection import StoreConnection
from service.store.tables import checkpoints, jobs, results

# The statements of a cold request's writes, built once: SQLAlchemy builds and keys a
# statement written inline on every call (~100-150 us each, the larger part of a small
# transaction's cost); a prebuilt one with bound parameters is keyed once (~20 us).
# Parameter names are ``b_*``: an UPDATE's column names are taken by its SET clause.
_JOB = select(jobs).where(jobs.c.key == bindparam("b_key"))
_JOB_LOCKED = _JOB.with_for_update()
_STORED = select(results.c.key).where(results.c.key == bindparam("b_key"))
#: whether any job waits in the durable queue (the dispatcher's read after every
#: computation that ends: built inline, 0.6 ms CPU per call, prebuilt 0.26 ms in-process)
_ANY_WAITING = (
    select(jobs.c.key)
    .where((jobs.c.status == JobState.QUEUED) & jobs.c.dispatcher.is_(None))
    .limit(1)
)
_DELETE_CHECKPOINTS = delete(checkpoints).where(checkpoints.c.key == bindparam("b_key"))


def _finish_statement(owned: bool, succeeded: bool) -> Any:
    """The UPDATE of :meth:`JobStore._finish` (of the lease ``b_owner`` if ``owned``)."""
    cond = [jobs.c.key == bindparam("b_key"), jobs.c.status.in_(ACTIVE)]
    if owned:
        cond.append(jobs.c.owner == bindparam("b_owner"))
    return (
        update(jobs)
        .where(*cond)
        .values(
            status=bindparam("b_status"),
            error=bindparam("b_error"),
            finished=bindparam("b_now"),
            updated=bindparam("b_now"),
            heartbeat=bindparam("b_now"),
            owner=None,
            progress=1.0 if succeeded else jobs.c.progress,
        )
    )


#: the ``dispatcher`` of a job driven at once by whoever wrote it (:meth:`JobStore.enqueue_job`
#: without a replica id: tests, tools)
DRIVEN = "direct"
#: the window of the cost-per-minute quota [s]
COST_WINDOW_S = 60.0


@dataclass(frozen=True)
class Job:
    """One job record; times are Unix seconds (UTC)."""

    key: str
    kind: str
    spec: dict[str, Any]
    status: JobState
    progress: float
    error: dict[str, Any] | None
    created: float
    started: float | None
    finished: float | None
    updated: float
    cancel: bool
    attempts: int = 0
    last_retry_reason: str | None = None
    refresh: bool = False
    generation: int = 1
    owner: str | None = None
    worker: str | None = None
    heartbeat: float | None = None
    principal: str | None = None
    dispatcher: str | None = None
    dispatched: float | None = None
    cost: float = 0.0

    @classmethod
    def from_row(cls, row: Row[Any]) -> Job:
        m = row._mapping
        return cls(
            key=m["key"],
            kind=m["kind"],
            spec=json.loads(m["spec"]),
            status=JobState(m["status"]),
            progress=float(m["progress"]),
            error=json.loads(m["error"]) if m["error"] else None,
            created=m["created"],
            started=m["started"],
            finished=m["finished"],
            updated=m["updated"],
            cancel=bool(m["cancel"]),
            attempts=int(m["attempts"]),
            last_retry_reason=m["last_retry_reason"],
            refresh=bool(m["refresh"]),
            generation=int(m["generation"]),
            owner=m["owner"],
            worker=m["worker"],
            heartbeat=m["heartbeat"],
            principal=m["principal"],
            dispatcher=m["dispatcher"],
            dispatched=m["dispatched"],
            cost=float(m["cost"]),
        )

    @property
    def active(self) -> bool:
        return self.status in ACTIVE

    @property
    def waiting(self) -> bool:
        """Accepted into the durable queue, not yet taken by a replica."""
        return self.status == JobState.QUEUED and self.dispatcher is None


@dataclass(frozen=True)
class Usage:
    """One client's jobs now (:meth:`JobStore.usage`): ``active`` (taken by a replica:
    computing or about to), ``waiting`` (in the durable queue), ``cost`` (summed estimated
    cost of the jobs it started in the last :data:`COST_WINDOW_S` [s], in units of each
    kind's cost bound) and ``oldest`` (when the oldest of those started [Unix s], None
    when none did)."""

    active: int
    waiting: int
    cost: float
    oldest: float | None


@dataclass(frozen=True)
class Claim:
    """What :meth:`Store.claim` found: ``"claimed"`` (compute now), ``"elsewhere"`` (a live
    attempt holds the lease), ``"done"`` (the job is finished or gone: nothing to do),
    ``"stored"`` (its result was stored already: the claim finished the job as succeeded);
    :meth:`Store.enqueue_and_claim` also ``"queued"`` (an active record was there first:
    not claimed)."""

    outcome: ClaimOutcome
    job: Job | None


class JobRecords(StoreConnection):
    """Job records, the replica side: created, shared or reset before a computation is
    accepted (the queue and the leases build on it: :class:`JobQueue`, :class:`JobStore`)."""

    def _job(self, conn: Connection, key: str, *, lock: bool = False) -> Job | None:
        row = conn.execute(_JOB_LOCKED if lock else _JOB, {"b_key": key}).first()
        return Job.from_row(row) if row is not None else None

    @functools.cached_property
    def _insert_job(self) -> Any:
        """INSERT of a job row unless its key exists (the columns are the parameters')."""
        return self._insert(jobs).on_conflict_do_nothing(index_elements=["key"])

    def _create_or_reset(
        self,
        conn: Connection,
        key: str,
        created: dict[str, Any],
        reset: dict[str, Any],
        keep_stored: bool = False,
    ) -> bool:
        """Insert job ``key`` with the ``created`` columns, or, if its row exists and is not
        active, update it with the ``reset`` columns (an active job is shared as it is);
        ``keep_stored``: a succeeded job whose result is stored is left as it is too.
        True if the row was inserted or reset (False: left as it was)."""
        inserted = conn.execute(self._insert_job, {"key": key, **created}).rowcount
        if inserted:
            return True
        resettable = [jobs.c.key == key, jobs.c.status.notin_(ACTIVE)]
        if keep_stored:
            stored = select(results.c.key).where(results.c.key == key).exists()
            resettable.append(~((jobs.c.status == JobState.SUCCEEDED) & stored))
        return bool(conn.execute(update(jobs).where(*resettable).values(**reset)).rowcount)

    def enqueue_job(
        self,
        key: str,
        kind: str,
        spec: dict[str, Any],
        *,
        refresh: bool = False,
        keep_stored: bool = False,
        principal: str | None = None,
        cost: float = 0.0,
        dispatcher: str = DRIVEN,
    ) -> Job:
        """Create the job record, or reset a finished one to queued (a new generation),
        driven at once by the replica ``dispatcher``; an active one is left as it is
        (identical requests share it; one waiting in the durable queue is taken by
        ``dispatcher``), and with ``keep_stored`` a succeeded one whose result is stored (a
        request joining a run that has just ended: resetting it would compute the same key
        again).  ``principal``: who asked; ``cost``: the estimate the quotas count."""
        with self._write() as conn:
            self._queue(conn, key, kind, spec, refresh, principal, cost, dispatcher, keep_stored)
            conn.execute(
                update(jobs)
                .where(
                    jobs.c.key == key, jobs.c.status == JobState.QUEUED, jobs.c.dispatcher.is_(None)
                )
                .values(dispatcher=dispatcher)
            )
            job = self._job(conn, key)
        assert job is not None  # written in this transaction
        return job

    def enqueue_and_claim(
        self,
        key: str,
        kind: str,
        spec: dict[str, Any],
        owner: str,
        worker: str,
        *,
        refresh: bool,
        principal: str | None = None,
        cost: float = 0.0,
        dispatcher: str | None = DRIVEN,
    ) -> Claim:
        """:meth:`enqueue_job` and :meth:`claim` in one transaction, for an attempt that
        starts computing right away in the process that accepts the job (the fast lane):
        the record is written already leased to ``owner`` on ``worker``, so there is never
        a moment where it is accepted but unowned, and one write fewer per job.

        ``"claimed"``: the record was created (or a finished one reset to a new
        generation) and is running under ``owner``; ``"stored"``: the result is stored and
        ``refresh`` is not asked, so the record was finished as succeeded (as
        :meth:`claim` does); ``"queued"``: an active record exists (another request or
        replica accepted it first): it is left as it is and not claimed, ``job`` is it,
        and the caller goes the ordinary way (:meth:`claim` by the attempt it submits).
        """
        with self._write() as conn:
            columns = _queued(kind, spec, refresh, principal, cost, dispatcher)
            if not refresh and self._stored(conn, key):
                if self._create_or_reset(conn, key, *columns):
                    self._finish(conn, key, JobState.SUCCEEDED, None, None)
                    return Claim(ClaimOutcome.STORED, self._job(conn, key))
                return Claim(ClaimOutcome.QUEUED, self._job(conn, key))
            created, reset = columns
            lease = dict(
                status=JobState.RUNNING,
                started=created["created"],
                owner=owner,
                worker=worker,
                attempts=1,
            )
            changed = self._create_or_reset(conn, key, created | lease, reset | lease)
            job = self._job(conn, key)
        return Claim(ClaimOutcome.CLAIMED if changed else ClaimOutcome.QUEUED, job)

    def _queue(
        self,
        conn: Connection,
        key: str,
        kind: str,
        spec: dict[str, Any],
        refresh: bool,
        principal: str | None,
        cost: float,
        dispatcher: str | None,
        keep_stored: bool = False,
    ) -> None:
        """Create or reset the record of ``key`` as queued (see :meth:`_create_or_reset`)."""
        self._create_or_reset(
            conn,
            key,
            *_queued(kind, spec, refresh, principal, cost, dispatcher),
            keep_stored=keep_stored,
        )

    def _finish(
        self,
        conn: Connection,
        key: str,
        status: JobState,
        error: dict[str, Any] | None,
        owner: str | None,
    ) -> bool:
        """:meth:`finish_job` inside the transaction ``conn``."""
        params = {
            "b_key": key,
            "b_owner": owner,
            "b_status": status,
            "b_error": json.dumps(error) if error else None,
            "b_now": time.time(),
        }
        statement = _FINISH[owner is not None, status == JobState.SUCCEEDED]
        done = conn.execute(statement, params).rowcount
        if done:
            conn.execute(_DELETE_CHECKPOINTS, {"b_key": key})
        return bool(done)

    @staticmethod
    def _stored(conn: Connection, key: str) -> bool:
        """Whether the results table holds ``key`` (read in ``conn``'s transaction)."""
        return conn.execute(_STORED, {"b_key": key}).first() is not None


class JobQueue(JobRecords):
    """The durable queue and the records' reads and upkeep (see the module docstring)."""

    @staticmethod
    def _is_waiting() -> Any:
        """A job waiting in the durable queue (as :data:`_ANY_WAITING` asks)."""
        return (jobs.c.status == JobState.QUEUED) & jobs.c.dispatcher.is_(None)

    def queue_job(
        self,
        key: str,
        kind: str,
        spec: dict[str, Any],
        *,
        bound: int,
        refresh: bool = False,
        principal: str | None = None,
        cost: float = 0.0,
    ) -> tuple[Job | None, bool]:
        """Accept job ``key`` into the durable queue: ``(record, True)`` once it is there
        (created, or a finished one reset to queued), ``(record, True)`` too for an active
        one (shared as it is), ``(record or None, False)`` when ``bound`` jobs wait already
        (the queue is full).  One transaction: the bound holds across replicas."""
        with self._write() as conn:
            job = self._job(conn, key)
            if job is not None and job.active:
                return job, True
            waiting = conn.execute(
                select(func.count()).select_from(jobs).where(self._is_waiting())
            ).scalar_one()
            if waiting >= bound:
                return job, False
            self._queue(conn, key, kind, spec, refresh, principal, cost, None)
            job = self._job(conn, key)
        return job, True

    def requeue_stale(self, stale_after_s: float) -> list[str]:
        """Put back into the durable queue the jobs a replica took (or accepted to drive)
        that no attempt has started and whose replica has not been heard of for
        ``stale_after_s`` [s] (it died between taking and starting them): they wait again
        for a free slot of any replica, in their turn, instead of being driven by whichever
        replica notices first, beyond its slots.  Returns their keys."""
        cond = [
            jobs.c.status == JobState.QUEUED,
            jobs.c.dispatcher.is_not(None),
            jobs.c.owner.is_(None),
            jobs.c.heartbeat.is_(None) | (jobs.c.heartbeat < time.time() - stale_after_s),
        ]
        with self._write() as conn:
            keys = [r.key for r in conn.execute(select(jobs.c.key).where(*cond))]
            if keys:
                conn.execute(
                    update(jobs)
                    .where(jobs.c.key.in_(keys), *cond)
                    .values(dispatcher=None, dispatched=None, heartbeat=time.time())
                )
        return keys

    def waiting_jobs(self) -> int:
        """Jobs in the durable queue (accepted, not yet taken by a replica)."""
        with self._read() as conn:
            return int(
                conn.execute(
                    select(func.count()).select_from(jobs).where(self._is_waiting())
                ).scalar_one()
            )

    def claim_waiting(self, dispatcher: str, n: int, per_principal: int | None = None) -> list[Job]:
        """Take up to ``n`` jobs from the durable queue for the replica ``dispatcher``.

        Fair between clients: each next job is the oldest waiting one of the client with
        the fewest active jobs (over every replica), ties to the client served longest ago
        (its last job taken from the queue; never: first), then to the one whose oldest
        job waits longest; within a client, oldest first.  So with one worker the clients
        take turns, whatever the length of their backlogs.  ``per_principal``: a client with
        that many active jobs gets none (its concurrency quota; its jobs wait).  Each job
        is taken by one conditional UPDATE (still waiting?), so two replicas never both
        take one (SQLite: one writer at a time; PostgreSQL: the second UPDATE re-reads
        the row after the first commits and matches nothing).  An empty queue is seen by
        a read first, without the write lock: the dispatcher looks each time one of the
        replica's computations ends, and a write transaction there queued every cold
        request's own writes behind it."""
        taken: list[Job] = []
        if n <= 0:
            return taken
        with self._read() as conn:
            if conn.execute(_ANY_WAITING).first() is None:
                return taken
        with self._write() as conn:
            who = func.coalesce(jobs.c.principal, "")
            active: dict[str, int] = dict(
                conn.execute(
                    select(who, func.count())
                    .where(jobs.c.status.in_(ACTIVE), jobs.c.dispatcher.is_not(None))
                    .group_by(who)
                ).all()
            )
            heads: dict[str, float] = dict(
                conn.execute(
                    select(who, func.min(jobs.c.created)).where(self._is_waiting()).group_by(who)
                ).all()
            )
            served: dict[str, float] = dict(
                conn.execute(
                    select(who, func.max(jobs.c.dispatched))
                    .where(who.in_(list(heads)), jobs.c.dispatched.is_not(None))
                    .group_by(who)
                ).all()
            )
            while len(taken) < n and heads:
                ready = [
                    p for p in heads if per_principal is None or active.get(p, 0) < per_principal
                ]
                if not ready:
                    break
                p = min(ready, key=lambda q: (active.get(q, 0), served.get(q, 0.0), heads[q], q))
                row = conn.execute(
                    select(jobs.c.key)
                    .where(self._is_waiting(), who == p)
                    .order_by(jobs.c.created, jobs.c.key)
                    .limit(1)
                ).first()
                if row is None:
                    del heads[p]
                    continue
                now = time.time()
                got = conn.execute(
                    update(jobs)
                    .where(jobs.c.key == row.key, self._is_waiting())
                    .values(dispatcher=dispatcher, dispatched=now, heartbeat=now)
                ).rowcount
                if got:
                    job = self._job(conn, row.key)
                    assert job is not None
                    taken.append(job)
                    active[p] = active.get(p, 0) + 1
                    served[p] = now
                nxt = conn.execute(
                    select(func.min(jobs.c.created)).where(self._is_waiting(), who == p)
                ).scalar_one()
                if nxt is None:
                    del heads[p]
                else:
                    heads[p] = nxt
        return taken

    def usage(self, principal: str, window_s: float = COST_WINDOW_S) -> Usage:
        """What the quotas count for ``principal`` (see :class:`Usage`), in one read."""
        since = time.time() - window_s
        mine = jobs.c.principal == principal
        with self._read() as conn:
            active, waiting = conn.execute(
                select(
                    func.count().filter(jobs.c.status.in_(ACTIVE), jobs.c.dispatcher.is_not(None)),
                    func.count().filter(self._is_waiting()),
                ).where(mine)
            ).one()
            cost, oldest = conn.execute(
                select(func.coalesce(func.sum(jobs.c.cost), 0.0), func.min(jobs.c.created)).where(
                    mine, jobs.c.created >= since
                )
            ).one()
        return Usage(int(active), int(waiting), float(cost), oldest)

    def finish_job(
        self,
        key: str,
        status: JobState,
        error: dict[str, Any] | None = None,
        *,
        owner: str | None = None,
    ) -> bool:
        """Move an active job to a terminal state (only if ``owner`` holds its lease, when
        given); a job already terminal is left alone.  True if this call finished it."""
        with self._write() as conn:
            return self._finish(conn, key, status, error, owner)

    def mark_succeeded(self, key: str, kind: str, spec: dict[str, Any]) -> None:
        """Record a job whose result is already stored (a resubmission of a cached run)."""
        created, _ = _queued(kind, spec, False)
        now = created["created"]
        with self._write() as conn:
            self._create_or_reset(
                conn,
                key,
                created | dict(status=JobState.SUCCEEDED, progress=1.0, started=now, finished=now),
                dict(
                    status=JobState.SUCCEEDED,
                    progress=1.0,
                    error=None,
                    finished=func.coalesce(jobs.c.finished, now),
                    updated=now,
                ),
            )

    def get_job(self, key: str) -> Job | None:
        with self._read() as conn:
            return self._job(conn, key)

    def active_jobs(self) -> list[Job]:
        with self._read() as conn:
            rows = conn.execute(
                select(jobs).where(jobs.c.status.in_(ACTIVE)).order_by(jobs.c.created)
            ).all()
        return [Job.from_row(r) for r in rows]

    def job_counts(self) -> dict[str, int]:
        """Job records by status (every status present, zeros included)."""
        with self._read() as conn:
            rows = conn.execute(select(jobs.c.status, func.count()).group_by(jobs.c.status)).all()
        counts = {str(status): int(n) for status, n in rows}
        # plain keys: a StrEnum key is refused by orjson (a value is written as its value)
        return {status.value: counts.get(status, 0) for status in STATUSES}

    def jobs_by_key(self, keys: Sequence[str]) -> dict[str, Job]:
        """The records of ``keys`` that exist (one query: the replica's monitor)."""
        if not keys:
            return {}
        with self._read() as conn:
            rows = conn.execute(select(jobs).where(jobs.c.key.in_(list(keys)))).all()
        return {job.key: job for job in map(Job.from_row, rows)}

    def stale_jobs(self, stale_after_s: float) -> list[Job]:
        """Active jobs whose owner (or submitter) has not been heard of for ``stale_after_s``
        (not those waiting in the durable queue: nobody holds them)."""
        limit = time.time() - stale_after_s
        with self._read() as conn:
            rows = conn.execute(
                select(jobs)
                .where(
                    jobs.c.status.in_(ACTIVE),
                    ~self._is_waiting(),
                    (jobs.c.heartbeat.is_(None)) | (jobs.c.heartbeat < limit),
                )
                .order_by(jobs.c.created)
            ).all()
        return [Job.from_row(r) for r in rows]

    def touch(self, keys: Sequence[str]) -> None:
        """Heartbeat of the submitter: queued jobs it still waits for are not stale."""
        if not keys:
            return
        with self._write() as conn:
            conn.execute(
                update(jobs)
                .where(jobs.c.key.in_(list(keys)), jobs.c.status == JobState.QUEUED)
                .values(heartbeat=time.time())
            )

    def note_retry(self, key: str, reason: str) -> None:
        """Record why an active job is being submitted again."""
        with self._write() as conn:
            conn.execute(
                update(jobs)
                .where(jobs.c.key == key, jobs.c.status.in_(ACTIVE))
                .values(last_retry_reason=reason, heartbeat=time.time())
            )

    def prune_jobs(self, older_than: float) -> int:
        """Delete finished job records whose last update is before ``older_than`` [Unix s],
        and the checkpoints of jobs no longer active (a finish deletes them already; this
        catches a write that raced it)."""
        with self._write() as conn:
            active = select(jobs.c.key).where(jobs.c.status.in_(ACTIVE))
            conn.execute(delete(checkpoints).where(checkpoints.c.key.notin_(active)))
            return int(
                conn.execute(
                    delete(jobs).where(jobs.c.status.notin_(ACTIVE), jobs.c.updated < older_than)
                ).rowcount
            )

    def computations(self) -> int:
        """Total attempts ever started over the job records (tests count recomputation)."""
        with self._read() as conn:
            return int(
                conn.execute(select(func.coalesce(func.sum(jobs.c.attempts), 0))).scalar_one()
            )


class JobStore(JobQueue):
    """Job records and their leases (see the module docstring): the task side, the attempt
    that computes, on top of the records and the queue."""

    def claim(self, key: str, owner: str, worker: str, stale_after_s: float) -> Claim:
        """Take the job's lease for the attempt ``owner`` running on ``worker``.

        A lease held by another attempt whose heartbeat is younger than ``stale_after_s``
        is respected; an older one is taken over (the retry's reason says why).  One
        transaction, the job's row locked (``SELECT ... FOR UPDATE``; SQLite: ``BEGIN
        IMMEDIATE``) from the check to the update, so two attempts never both claim.  A
        job whose result is already stored (and not asked to be recomputed) is finished
        in the same transaction instead (``"stored"``).
        """
        now = time.time()
        with self._write() as conn:
            job = self._job(conn, key, lock=True)
            if job is None or not job.active or job.cancel:
                return Claim(ClaimOutcome.DONE, job)
            if job.owner == owner:
                return Claim(ClaimOutcome.CLAIMED, job)
            age = now - (job.heartbeat or 0.0)
            if job.owner is not None and age < stale_after_s:
                return Claim(ClaimOutcome.ELSEWHERE, job)
            if not job.refresh and self._stored(conn, key):
                # computed by an earlier attempt (which died before finishing the record):
                # finished here, in the claim's transaction
                self._finish(conn, key, JobState.SUCCEEDED, None, None)
                return Claim(ClaimOutcome.STORED, self._job(conn, key))
            reason = job.last_retry_reason
            if job.owner is not None:
                reason = (
                    f"attempt {job.attempts} on {job.worker or 'an unknown worker'} stopped "
                    f"heartbeating ({age:.1f} s without a sign of life)"
                )
            conn.execute(
                update(jobs)
                .where(jobs.c.key == key)
                .values(
                    status=JobState.RUNNING,
                    started=now,
                    updated=now,
                    heartbeat=now,
                    progress=0.0,
                    owner=owner,
                    worker=worker,
                    attempts=jobs.c.attempts + 1,
                    last_retry_reason=reason,
                )
            )
            return Claim(ClaimOutcome.CLAIMED, self._job(conn, key))

    def heartbeat(self, key: str, owner: str, progress: float | None = None) -> LeaseState:
        """Renew the lease (and record ``progress`` in [0, 1]): ``"ok"``, ``"cancelled"``
        (stop: the job was cancelled) or ``"lost"`` (another attempt owns the job now)."""
        now = time.time()
        values: dict[str, Any] = {"heartbeat": now, "updated": now}
        if progress is not None:
            p = min(max(progress, 0.0), 1.0)
            values["progress"] = case((jobs.c.progress < p, p), else_=jobs.c.progress)
        with self._write() as conn:
            renewed = conn.execute(
                update(jobs)
                .where(
                    jobs.c.key == key,
                    jobs.c.owner == owner,
                    jobs.c.status == JobState.RUNNING,
                    jobs.c.cancel == 0,
                )
                .values(**values)
            ).rowcount
            if renewed:
                return LeaseState.OK
            job = self._job(conn, key)
        if job is not None and (job.cancel or job.status == JobState.CANCELLED):
            return LeaseState.CANCELLED
        return LeaseState.LOST

    def release(
        self, key: str, owner: str, reason: str | None = None, refund: bool = False
    ) -> None:
        """Give up the lease without finishing (the job is retried; ``reason`` says why).
        ``refund``: the attempt stopped in good order before its work (the fast lane's
        hand-off) and does not count against the job's attempts (:data:`MAX_ATTEMPTS` of
        the runner bounds the starts whose process died)."""
        with self._write() as conn:
            values: dict[str, Any] = {"owner": None, "heartbeat": time.time()}
            if reason is not None:
                values["last_retry_reason"] = reason
            if refund:
                values["attempts"] = jobs.c.attempts - 1
            conn.execute(
                update(jobs).where(jobs.c.key == key, jobs.c.owner == owner).values(**values)
            )

    def save_checkpoint(self, key: str, generation: int, owner: str, body: bytes) -> bool:
        """Keep ``body`` as the latest checkpoint of generation ``generation`` of job ``key``
        (replacing the previous one), if the attempt ``owner`` still holds its running
        lease; True if kept.  The job's row is locked from the check to the write, so a
        finish (which deletes the job's checkpoints) is never followed by a stray row."""
        now = time.time()
        with self._write() as conn:
            held = conn.execute(
                select(jobs.c.key)
                .where(
                    jobs.c.key == key,
                    jobs.c.generation == generation,
                    jobs.c.owner == owner,
                    jobs.c.status == JobState.RUNNING,
                )
                .with_for_update()
            ).first()
            if held is None:
                return False
            row = dict(body=body, size=len(body), written=now)
            conn.execute(
                self._insert(checkpoints)
                .values(key=key, generation=generation, **row)
                .on_conflict_do_update(index_elements=["key", "generation"], set_=row)
            )
        return True

    def load_checkpoint(self, key: str, generation: int) -> bytes | None:
        """The latest checkpoint of generation ``generation`` of job ``key``, or None."""
        with self._read() as conn:
            body = conn.execute(
                select(checkpoints.c.body).where(
                    checkpoints.c.key == key, checkpoints.c.generation == generation
                )
            ).scalar_one_or_none()
        return bytes(body) if body is not None else None

    def checkpoint_sizes(self) -> dict[str, int]:
        """The stored checkpoints' sizes by job key [bytes] (tests, inspection)."""
        with self._read() as conn:
            rows = conn.execute(select(checkpoints.c.key, checkpoints.c.size)).all()
        return {str(key): int(size) for key, size in rows}

    def expire_leases(self, worker: str, heartbeat: float) -> list[str]:
        """The worker ``worker`` left the cluster (Dask's own signal): the leases of the
        active jobs it held are dated back to ``heartbeat`` [Unix s] (the caller passes
        now - stale_after_s), so the next attempt takes them over at once; an attempt
        that is in fact alive finds its lease taken at its next heartbeat (``"lost"``).
        Returns the keys of those jobs."""
        cond = [
            jobs.c.worker == worker,
            jobs.c.owner.is_not(None),
            jobs.c.status.in_(ACTIVE),
            jobs.c.heartbeat > heartbeat,
        ]
        with self._write() as conn:
            keys = [r.key for r in conn.execute(select(jobs.c.key).where(*cond))]
            if keys:
                conn.execute(update(jobs).where(*cond).values(heartbeat=heartbeat))
            return keys


def _queued(
    kind: str,
    spec: dict[str, Any],
    refresh: bool,
    principal: str | None = None,
    cost: float = 0.0,
    dispatcher: str | None = None,
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The columns of a job record accepted now and queued: ``(created, reset)``, those of
    a new row and those that reset a finished row to a new generation
    (:meth:`JobStore._create_or_reset`)."""
    now = time.time()
    created: dict[str, Any] = dict(
        kind=kind,
        spec=json.dumps(spec),
        status=JobState.QUEUED,
        progress=0.0,
        created=now,
        updated=now,
        heartbeat=now,
        refresh=refresh,
        principal=principal,
        dispatcher=dispatcher,
        cost=cost,
    )
    reset: dict[str, Any] = created | dict(
        error=None,
        started=None,
        finished=None,
        cancel=0,
        attempts=0,
        last_retry_reason=None,
        generation=jobs.c.generation + 1,
        owner=None,
        worker=None,
    )
    return created, reset


#: :func:`_finish_statement` by (owned, succeeded)
_FINISH = {(o, s): _finish_statement(o, s) for o in (False, True) for s in (False, True)}
