"""The jobs half of the store: one record per job key, written before a computation is
accepted (replica side), whose lease (``owner`` + ``heartbeat``) the attempt computing it
holds (task side), so a job whose heartbeat went stale can be taken over by any live
replica, and two replicas never compute one job at once.
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal, get_args

from sqlalchemy import Connection, Row, case, delete, func, select, update

from service.store.connection import StoreConnection
from service.store.tables import jobs, results

#: a job's status: the one definition (the job record's column, the HTTP job document)
JobState = Literal["queued", "running", "succeeded", "failed", "cancelled"]
STATUSES: tuple[str, ...] = get_args(JobState)
ACTIVE = ("queued", "running")  # not yet ended


@dataclass(frozen=True)
class Job:
    """One job record; times are Unix seconds (UTC)."""

    key: str
    kind: str
    spec: dict[str, Any]
    status: str
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

    @classmethod
    def from_row(cls, row: Row[Any]) -> Job:
        m = row._mapping
        return cls(
            key=m["key"],
            kind=m["kind"],
            spec=json.loads(m["spec"]),
            status=m["status"],
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
        )

    @property
    def active(self) -> bool:
        return self.status in ACTIVE


@dataclass(frozen=True)
class Claim:
    """What :meth:`Store.claim` found: ``"claimed"`` (compute now), ``"elsewhere"`` (a live
    attempt holds the lease), ``"done"`` (the job is finished or gone: nothing to do),
    ``"stored"`` (its result was stored already: the claim finished the job as succeeded)."""

    outcome: str
    job: Job | None


class JobStore(StoreConnection):
    """Job records and their leases (see the module docstring)."""

    # -- jobs (replica side) --------------------------------------------------------------

    def _job(self, conn: Connection, key: str, *, lock: bool = False) -> Job | None:
        query = select(jobs).where(jobs.c.key == key)
        row = conn.execute(query.with_for_update() if lock else query).first()
        return Job.from_row(row) if row is not None else None

    def _create_or_reset(
        self,
        conn: Connection,
        key: str,
        created: dict[str, Any],
        reset: dict[str, Any],
        keep_stored: bool = False,
    ) -> None:
        """Insert job ``key`` with the ``created`` columns, or, if its row exists and is not
        active, update it with the ``reset`` columns (an active job is shared as it is);
        ``keep_stored``: a succeeded job whose result is stored is left as it is too."""
        inserted = conn.execute(
            self._insert(jobs)
            .values(key=key, **created)
            .on_conflict_do_nothing(index_elements=["key"])
        ).rowcount
        if not inserted:
            resettable = [jobs.c.key == key, jobs.c.status.notin_(ACTIVE)]
            if keep_stored:
                stored = select(results.c.key).where(results.c.key == key).exists()
                resettable.append(~((jobs.c.status == "succeeded") & stored))
            conn.execute(update(jobs).where(*resettable).values(**reset))

    def enqueue_job(
        self,
        key: str,
        kind: str,
        spec: dict[str, Any],
        *,
        refresh: bool = False,
        keep_stored: bool = False,
    ) -> Job:
        """Create the job record, or reset a finished one to queued (a new generation);
        an active one is left as it is (identical requests share it), and with
        ``keep_stored`` a succeeded one whose result is stored (a request joining a run
        that has just ended: resetting it would compute the same key again)."""
        now = time.time()
        with self._write() as conn:
            self._create_or_reset(
                conn,
                key,
                dict(
                    kind=kind,
                    spec=json.dumps(spec),
                    status="queued",
                    progress=0.0,
                    created=now,
                    updated=now,
                    heartbeat=now,
                    refresh=refresh,
                ),
                dict(
                    kind=kind,
                    spec=json.dumps(spec),
                    status="queued",
                    progress=0.0,
                    error=None,
                    created=now,
                    started=None,
                    finished=None,
                    updated=now,
                    cancel=0,
                    attempts=0,
                    last_retry_reason=None,
                    refresh=refresh,
                    generation=jobs.c.generation + 1,
                    owner=None,
                    worker=None,
                    heartbeat=now,
                ),
                keep_stored=keep_stored,
            )
            job = self._job(conn, key)
        assert job is not None  # written in this transaction
        return job

    def finish_job(
        self,
        key: str,
        status: str,
        error: dict[str, Any] | None = None,
        *,
        owner: str | None = None,
    ) -> bool:
        """Move an active job to a terminal state (only if ``owner`` holds its lease, when
        given); a job already terminal is left alone.  True if this call finished it."""
        with self._write() as conn:
            return self._finish(conn, key, status, error, owner)

    def _finish(
        self,
        conn: Connection,
        key: str,
        status: str,
        error: dict[str, Any] | None,
        owner: str | None,
    ) -> bool:
        """:meth:`finish_job` inside the transaction ``conn``."""
        now = time.time()
        cond = [jobs.c.key == key, jobs.c.status.in_(ACTIVE)]
        if owner is not None:
            cond.append(jobs.c.owner == owner)
        done = conn.execute(
            update(jobs)
            .where(*cond)
            .values(
                status=status,
                error=json.dumps(error) if error else None,
                finished=now,
                updated=now,
                heartbeat=now,
                owner=None,
                progress=1.0 if status == "succeeded" else jobs.c.progress,
            )
        ).rowcount
        return bool(done)

    def mark_succeeded(self, key: str, kind: str, spec: dict[str, Any]) -> None:
        """Record a job whose result is already stored (a resubmission of a cached run)."""
        now = time.time()
        with self._write() as conn:
            self._create_or_reset(
                conn,
                key,
                dict(
                    kind=kind,
                    spec=json.dumps(spec),
                    status="succeeded",
                    progress=1.0,
                    created=now,
                    started=now,
                    finished=now,
                    updated=now,
                ),
                dict(
                    status="succeeded",
                    progress=1.0,
                    error=None,
                    finished=func.coalesce(jobs.c.finished, now),
                    updated=now,
                ),
            )

    def request_cancel(self, key: str) -> Job | None:
        """Flag an active job as cancelled (its attempt stops at its next heartbeat)."""
        now = time.time()
        with self._write() as conn:
            conn.execute(
                update(jobs)
                .where(jobs.c.key == key, jobs.c.status.in_(ACTIVE))
                .values(
                    cancel=1,
                    status="cancelled",
                    finished=now,
                    updated=now,
                    error=json.dumps({"detail": "cancelled by request"}),
                )
            )
            return self._job(conn, key)

    @staticmethod
    def _stored(conn: Connection, key: str) -> bool:
        """Whether the results table holds ``key`` (read in ``conn``'s transaction)."""
        found = conn.execute(select(results.c.key).where(results.c.key == key)).first()
        return found is not None

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
        return {status: counts.get(status, 0) for status in STATUSES}

    def jobs_by_key(self, keys: Sequence[str]) -> dict[str, Job]:
        """The records of ``keys`` that exist (one query: the replica's monitor)."""
        if not keys:
            return {}
        with self._read() as conn:
            rows = conn.execute(select(jobs).where(jobs.c.key.in_(list(keys)))).all()
        return {job.key: job for job in map(Job.from_row, rows)}

    def stale_jobs(self, stale_after_s: float) -> list[Job]:
        """Active jobs whose owner (or submitter) has not been heard of for ``stale_after_s``."""
        limit = time.time() - stale_after_s
        with self._read() as conn:
            rows = conn.execute(
                select(jobs)
                .where(
                    jobs.c.status.in_(ACTIVE),
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
                .where(jobs.c.key.in_(list(keys)), jobs.c.status == "queued")
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
        """Delete finished job records whose last update is before ``older_than`` [Unix s]."""
        with self._write() as conn:
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

    # -- jobs (task side: the attempt that computes) ---------------------------------------

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
                return Claim("done", job)
            if job.owner == owner:
                return Claim("claimed", job)
            age = now - (job.heartbeat or 0.0)
            if job.owner is not None and age < stale_after_s:
                return Claim("elsewhere", job)
            if not job.refresh and self._stored(conn, key):
                # computed by an earlier attempt (which died before finishing the record):
                # finished here, in the claim's transaction
                self._finish(conn, key, "succeeded", None, None)
                return Claim("stored", self._job(conn, key))
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
                    status="running",
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
            return Claim("claimed", self._job(conn, key))

    def heartbeat(self, key: str, owner: str, progress: float | None = None) -> str:
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
                    jobs.c.status == "running",
                    jobs.c.cancel == 0,
                )
                .values(**values)
            ).rowcount
            if renewed:
                return "ok"
            job = self._job(conn, key)
        if job is not None and (job.cancel or job.status == "cancelled"):
            return "cancelled"
        return "lost"

    def release(self, key: str, owner: str, reason: str | None = None) -> None:
        """Give up the lease without finishing (the job is retried; ``reason`` says why)."""
        with self._write() as conn:
            values: dict[str, Any] = {"owner": None, "heartbeat": time.time()}
            if reason is not None:
                values["last_retry_reason"] = reason
            conn.execute(
                update(jobs).where(jobs.c.key == key, jobs.c.owner == owner).values(**values)
            )

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
