"""/v1/jobs/{key}: status, progress and cancellation of any job.

Jobs are submitted at ``POST /v1/<computation>/jobs`` (:mod:`service.routes.computations`;
``POST /v1/jobs`` is the simulations' alias)."""

from __future__ import annotations

import asyncio
from typing import Annotated

from fastapi import APIRouter, Depends, Path, Query
from fastapi.responses import JSONResponse

from service.deps import RunnerDep, StoreDep
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
async def get_job(key: Key, store: StoreDep, runner: RunnerDep, wait: Wait = 0.0) -> JSONResponse:
    """The job's record; with ``wait`` > 0 a long poll: the answer comes when the job has
    ended or ``wait`` seconds have passed, whichever is first (instead of polling)."""
    job = await asyncio.to_thread(store.get_job, key)
    if job is None:
        raise ProblemError(404, f"no job {key}", slug="unknown-key")
    return job_response(await runner.wait_job(job, wait))


@router.delete(
    "/{key}",
    operation_id="cancelJob",
    summary="Cancel a queued or running job",
    response_model=JobStatus,
    responses=responses(404, 406, 409, 422),
)
async def cancel_job(key: Key, store: StoreDep, runner: RunnerDep) -> JSONResponse:
    """Cancel the job: it reports ``cancelled`` at once and its worker stops at its next
    progress check; a resubmission waits for that and runs it again.  Cancelling a
    cancelled job is a no-op; a finished one is a 409."""
    runner.cancel(key)  # before the record: a POST from now on starts a new run
    job = await asyncio.to_thread(store.request_cancel, key)
    runner.job_changed(key)  # its long polls answer (cancelled, or its final status)
    if job is None:
        raise ProblemError(404, f"no job {key}", slug="unknown-key")
    if job.status in ("succeeded", "failed"):
        raise ProblemError(409, f"job {key} already {job.status}", slug="job-finished")
    return job_response(job)
