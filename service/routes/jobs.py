"""/v1/jobs: asynchronous simulations with status, progress and cancellation."""

from __future__ import annotations

import asyncio
from typing import Annotated

from fastapi import APIRouter, Path
from fastapi.responses import JSONResponse

from service.compute import JOB_ACCEPTED, Refresh, accept_job, job_response
from service.deps import RunnerDep, StoreDep
from service.kinds import SIMULATION
from service.problems import ProblemError, responses
from service.routes.simulations import SpecBody
from service.schemas import KEY_PATTERN, JobStatus

router = APIRouter(prefix="/v1/jobs", tags=["jobs"])

Key = Annotated[str, Path(pattern=KEY_PATTERN, description="Job id = parameter hash.")]


@router.post(
    "",
    operation_id="submitJob",
    summary="Submit a simulation as a job",
    status_code=202,
    response_model=JobStatus,
    responses={**JOB_ACCEPTED, **responses(413, 422, 503)},
)
async def submit_simulation_job(
    spec: SpecBody, runner: RunnerDep, store: StoreDep, refresh: Refresh = False
) -> JSONResponse:
    """Accept the simulation (persisted before the answer) and return its job at once.
    The job id is the parameter hash: resubmitting is idempotent, a finished result is
    reused, and a failed or cancelled job is run again."""
    return await accept_job(runner, store, SIMULATION, spec, refresh)


@router.get(
    "/{key}",
    operation_id="getJob",
    summary="Job status, progress and timestamps",
    response_model=JobStatus,
    responses=responses(404, 422),
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
    responses=responses(404, 409, 422),
)
async def cancel_job(key: Key, store: StoreDep) -> JSONResponse:
    """Cancel the job: it reports ``cancelled`` at once and its worker stops at its next
    progress check.  Cancelling a cancelled job is a no-op; a finished one is a 409."""
    job = await asyncio.to_thread(store.request_cancel, key)
    if job is None:
        raise ProblemError(404, f"no job {key}", slug="unknown-key")
    if job.status in ("succeeded", "failed"):
        raise ProblemError(409, f"job {key} already {job.status}", slug="job-finished")
    return job_response(job)
