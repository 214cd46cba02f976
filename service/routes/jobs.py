"""/v1/jobs/{key}: status, progress and cancellation of a job.

Jobs are submitted at ``POST /v1/<computation>/jobs`` (:mod:`service.routes.computations`;
``POST /v1/jobs`` is the simulations' alias).  With API keys required, a client sees the
jobs it started or joined and cancels those it started (an admin key: all); any other job
is an unknown key to it (:mod:`service.http.access`)."""

from __future__ import annotations

import asyncio
from typing import Annotated

from fastapi import APIRouter, Depends, Path, Query
from fastapi.responses import JSONResponse

from service.deps import RunnerDep, StoreDep
from service.engine.lifecycle import JobState
from service.http.access import CallerDep, not_owner, unknown_job, visible_job
from service.http.negotiation import JSON, accepts
from service.http.problems import ProblemError, responses
from service.http.responses import job_response
from service.schemas import KEY_PATTERN, JobStatus

router = APIRouter(prefix="/v1/jobs", tags=["jobs"], dependencies=[Depends(accepts(JSON))])

Key = Annotated[str, Path(pattern=KEY_PATTERN, description="Job id = parameter hash.")]

#: longest long poll a request may ask for [s] (``GET /v1/jobs/{key}?wait=``)
MAX_WAIT_S = 60.0

Wait = Annotated[
    float,
    Query(
        ge=0,
        le=MAX_WAIT_S,
        description="Long poll [s]: answer as soon as the job has ended (succeeded, failed, "
        f"cancelled) or after this long with its current status; 0 <= wait <= {MAX_WAIT_S:g}. "
        "0 (default): at once.  A server holding too many long polls answers at once.",
    ),
]


@router.get(
    "/{key}",
    operation_id="getJob",
    summary="Job status, progress and timestamps",
    response_model=JobStatus,
    responses=responses(404, 406, 422),
)
async def get_job(
    key: Key, store: StoreDep, runner: RunnerDep, who: CallerDep, wait: Wait = 0.0
) -> JSONResponse:
    """The job's record; with ``wait`` > 0 a long poll: the answer comes when the job has
    ended or ``wait`` seconds have passed, whichever is first (instead of polling).  With
    API keys required: the jobs this key started or joined (an admin key: any); another
    client's job is a 404, as an unknown key is."""
    job = await visible_job(store, who, key)
    ended = await runner.wait_job(job, wait)
    if ended.generation != job.generation and not who.unrestricted:
        # reset meanwhile by another request: a new run, seen only if this key's too
        ended = await visible_job(store, who, key)
    return job_response(ended)


@router.delete(
    "/{key}",
    operation_id="cancelJob",
    summary="Cancel a queued or running job",
    response_model=JobStatus,
    responses=responses(404, 406, 409, 422),
)
async def cancel_job(key: Key, store: StoreDep, runner: RunnerDep, who: CallerDep) -> JSONResponse:
    """Cancel the job: it reports ``cancelled`` at once and its worker stops at its next
    progress check; a resubmission waits for that and runs it again.  Cancelling a
    cancelled job is a no-op; a finished one is a 409.  With API keys required: only the
    key that started the run, or an admin key, cancels it (403 for a key that joined it);
    another client's job is a 404, as an unknown key is."""
    job = await visible_job(store, who, key)
    if job.active and not who.owns(job):
        raise not_owner(key)
    if who.owns(job):
        runner.cancel(key)  # before the record: a POST from now on starts a new run
    # only this client's run (the record may have been reset by another since it was read)
    only = None if who.unrestricted else who.principal
    after = await asyncio.to_thread(store.request_cancel, key, only)
    runner.job_changed(key)  # its long polls answer (cancelled, or its final status)
    if after is None:
        raise unknown_job(key)
    if after.status in (JobState.SUCCEEDED, JobState.FAILED):
        raise ProblemError(409, f"job {key} already {after.status}", slug="job-finished")
    if after.active:  # another client's run now
        raise not_owner(key)
    return job_response(after)
