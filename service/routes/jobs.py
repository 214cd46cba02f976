"""/v1/jobs/{key}: status, progress and cancellation of any job.

Jobs are submitted at ``POST /v1/<computation>/jobs`` (:mod:`service.routes.computations`;
``POST /v1/jobs`` is the simulations' alias)."""

from __future__ import annotations

import asyncio
from typing import Annotated

from fastapi import APIRouter, Depends, Path
from fastapi.responses import JSONResponse

from service.deps import RunnerDep, StoreDep
from service.http.negotiation import JSON, accepts
from service.http.problems import ProblemError, responses
from service.http.responses import job_response
from service.schemas import KEY_PATTERN, JobStatus

router = APIRouter(prefix="/v1/jobs", tags=["jobs"], dependencies=[Depends(accepts(JSON))])

Key = Annotated[str, Path(pattern=KEY_PATTERN, description="Job id = parameter hash.")]


@router.get(
    "/{key}",
    operation_id="getJob",
    summary="Job status, progress and timestamps",
    response_model=JobStatus,
    responses=responses(404, 406, 422),
)
async def get_job(key: Key, store: StoreDep) -> JSONResponse:
    job = await asyncio.to_thread(store.get_job, key)
    if job is None:
        raise ProblemError(404, f"no job {key}", slug="unknown-key")
    return job_response(job)


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
    if job is None:
        raise ProblemError(404, f"no job {key}", slug="unknown-key")
    if job.status in ("succeeded", "failed"):
        raise ProblemError(409, f"job {key} already {job.status}", slug="job-finished")
    return job_response(job)
