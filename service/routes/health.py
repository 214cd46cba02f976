"""Liveness and readiness probes.

``/healthz`` (liveness) answers as soon as the process serves HTTP, the engine's start-up
included; ``/readyz`` answers 200 once the workers are warm, the scheduler has a worker
(followed from Dask's worker events), the store is writable and the queue has room.
"""

from __future__ import annotations

from fastapi import APIRouter, Depends

from pipeflow import __version__
from service.deps import RunnerDep
from service.http.negotiation import JSON, accepts
from service.http.problems import ProblemError, responses
from service.schemas import Health, Readiness

router = APIRouter(tags=["health"], dependencies=[Depends(accepts(JSON))])


@router.get(
    "/healthz",
    operation_id="getHealth",
    summary="Liveness",
    response_model=Health,
    responses=responses(406),
)
async def healthz() -> Health:
    """The process is up and serving HTTP."""
    return Health(version=__version__)


@router.get(
    "/readyz",
    operation_id="getReadiness",
    summary="Readiness: warm workers connected and a free slot",
    response_model=Readiness,
    responses=responses(406, 503),
)
async def readyz(runner: RunnerDep) -> Readiness:
    """200 when the workers are warm, the scheduler has at least one worker, the store is
    writable and the queue has room, else 503 with Retry-After [s]."""
    if runner.no_worker:
        raise ProblemError(
            503,
            "the Dask scheduler has no worker: no computation can run",
            slug="no-worker",
            headers={"Retry-After": str(runner.settings.retry_after_s)},
        )
    if not runner.ready:
        raise ProblemError(
            503,
            "worker processes are starting",
            slug="not-ready",
            headers={"Retry-After": "1"},
        )
    if not runner.store.healthy:
        raise ProblemError(
            503,
            f"the store is failing ({runner.store.last_error}); retrying by itself",
            slug="storage",
            headers={"Retry-After": str(runner.settings.retry_after_s)},
        )
    if runner.saturated:
        raise ProblemError(
            503,
            "the computation queue is full",
            slug="saturated",
            headers={"Retry-After": str(runner.settings.retry_after_s)},
        )
    return Readiness(workers=runner.workers, in_flight=runner.in_flight, capacity=runner.capacity)
