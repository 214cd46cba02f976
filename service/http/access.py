"""Who may see and cancel a job when the server requires API keys (issue 34, item 3).

A result is content addressed: its key is the hash of the request, so anyone who can
compute it can read it (``GET /v1/results/{key}``), and any key may submit it.  A job
record is not: it says that some client ran the computation, when, how far it got and
who it was (its ``principal``), so with keys required

- ``GET /v1/jobs/{key}`` shows a record to the key that started its current run (the
  record's ``principal``), to a key that joined that run (submitted the same computation
  while it was the record's, :mod:`service.store.grants`), and to an admin key
  (``PIPEFLOW_ADMIN_KEY_IDS``);
- ``DELETE /v1/jobs/{key}`` cancels a run for the key that started it and for an admin
  key only: a key that joined it sees it but gets a 403 (its cancel would stop another
  client's computation);
- any other key gets the 404 of an unknown key, for both methods, with the same body: a
  key cannot probe for the jobs of others (a 403 would confirm that the job exists).

Without keys (the default, one anonymous client) every job is everyone's, as before.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, Request

from service.http.auth import admin_ids
from service.http.problems import ProblemError
from service.settings import Settings
from service.store import Job, Store


@dataclass(frozen=True)
class Caller:
    """The client of a request to the job routes: ``principal`` (its key id; None with
    keys off) and whether it sees every job (keys off, or an admin key)."""

    principal: str | None
    unrestricted: bool

    def owns(self, job: Job) -> bool:
        """Whether this client may cancel ``job``'s run."""
        return self.unrestricted or job.principal == self.principal


async def caller(request: Request) -> Caller:
    """The :class:`Caller` of ``request`` (a FastAPI dependency)."""
    settings: Settings = request.app.state.settings
    who = getattr(request.state, "principal", None)
    if not settings.auth_required or who is None:
        # keys off; or an open path, which the job routes are not (the middleware answered)
        return Caller(None, True)
    return Caller(str(who), str(who) in admin_ids(settings))


CallerDep = Annotated[Caller, Depends(caller)]


def unknown_job(key: str) -> ProblemError:
    """The 404 of a job that does not exist, or that the client may not see (the same)."""
    return ProblemError(404, f"no job {key}", slug="unknown-key")


async def visible_job(store: Store, who: Caller, key: str) -> Job:
    """The record of job ``key`` if ``who`` may see it, else the 404 of an unknown key."""
    if who.unrestricted:
        job = await asyncio.to_thread(store.get_job, key)
        seen = job is not None
    else:
        assert who.principal is not None
        job, seen = await asyncio.to_thread(store.job_seen_by, key, who.principal)
    if job is None or not seen:
        raise unknown_job(key)
    return job


def not_owner(key: str) -> ProblemError:
    """The 403 of a key that sees a run it did not start and asks to cancel it."""
    return ProblemError(
        403,
        f"job {key} is another API key's run of this computation (yours joined it): only "
        "the key that started it, or an admin key (PIPEFLOW_ADMIN_KEY_IDS), can cancel it",
        slug="forbidden",
    )
