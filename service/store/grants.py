"""Who may follow a job besides the client that started its run, and a cancel that holds
for that client's run only (issue 34, item 3).

A job record's ``principal`` is the client whose request created it or reset it to a new
generation (its run).  Job keys are content addressed, so another client submitting the
same computation joins that run instead of starting its own: it is answered 202 with the
shared record, and :meth:`GrantStore.grant` records that it may follow the record's
current generation too (``job_grants``).  The job routes read a record with
:meth:`GrantStore.job_seen_by`; who may see or cancel what is decided in
:mod:`service.http.access`.
"""

from __future__ import annotations

import json
import time

from sqlalchemy import bindparam, delete, select, update

from service.store.jobs import ACTIVE, Job, JobState, JobStore
from service.store.tables import checkpoints, job_grants, jobs

_GRANTED = select(job_grants.c.generation).where(
    job_grants.c.key == bindparam("b_key"), job_grants.c.principal == bindparam("b_principal")
)


class GrantStore(JobStore):
    """Job records with the clients granted to follow them (see the module docstring)."""

    def grant(self, key: str, principal: str, generation: int) -> None:
        """Let ``principal`` follow generation ``generation`` of job ``key`` (a later
        grant of the same client replaces an earlier one)."""
        row = {"generation": generation}
        with self._write() as conn:
            conn.execute(
                self._insert(job_grants)
                .values(key=key, principal=principal, **row)
                .on_conflict_do_update(index_elements=["key", "principal"], set_=row)
            )

    def job_seen_by(self, key: str, principal: str) -> tuple[Job | None, bool]:
        """The record of job ``key`` and whether ``principal`` started its current run or
        was granted it (one read; the grant is looked up only for another's record)."""
        with self._read() as conn:
            job = self._job(conn, key)
            if job is None or job.principal == principal:
                return job, job is not None
            granted = conn.execute(_GRANTED, {"b_key": key, "b_principal": principal}).first()
        return job, granted is not None and granted.generation == job.generation

    def request_cancel(self, key: str, principal: str | None = None) -> Job | None:
        """Flag an active job as cancelled (its attempt stops at its next heartbeat) and
        return its record.  ``principal``: only if its current run is that client's (the
        check and the flag in one statement: a record reset meanwhile by another client's
        request is left running)."""
        now = time.time()
        cond = [jobs.c.key == key, jobs.c.status.in_(ACTIVE)]
        if principal is not None:
            cond.append(jobs.c.principal == principal)
        with self._write() as conn:
            flagged = conn.execute(
                update(jobs)
                .where(*cond)
                .values(
                    cancel=1,
                    status=JobState.CANCELLED,
                    finished=now,
                    updated=now,
                    error=json.dumps({"detail": "cancelled by request"}),
                )
            ).rowcount
            if flagged:
                conn.execute(delete(checkpoints).where(checkpoints.c.key == key))
            return self._job(conn, key)

    def prune_grants(self) -> int:
        """Delete the grants of job records that are gone or have moved on to a newer
        generation; how many."""
        current = select(jobs.c.key).where(
            jobs.c.key == job_grants.c.key, jobs.c.generation == job_grants.c.generation
        )
        with self._write() as conn:
            return int(conn.execute(delete(job_grants).where(~current.exists())).rowcount)
