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
from service.http.problems import STORAGE_CAUSES, ProblemError, responses
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
    writable and the queue has room, else 503 with Retry-After [s] and the reason (for the
    store: full or not writable; the driver's message is only logged)."""
    retry = runner.settings.retry_after_s
    for failing, detail, slug, retry_after in (
        (
            runner.no_worker,
            "the Dask scheduler has no worker: no computation can run",
            "no-worker",
            retry,
        ),
        (not runner.ready, "worker processes are starting", "not-ready", 1),
        (
            not runner.store.healthy,
            # the cause, never the driver's text (that is in the log)
            f"{STORAGE_CAUSES[runner.store.last_full]}; retrying by itself",
            "storage",
            retry,
        ),
        (runner.saturated, "the computation queue is full", "saturated", retry),
    ):
        if failing:
            raise ProblemError(503, detail, slug=slug, headers={"Retry-After": str(retry_after)})
    return Readiness(workers=runner.workers, in_flight=runner.in_flight, capacity=runner.capacity)
