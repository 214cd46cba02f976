"""POST /v1/stability (critical flow velocities, answered at once) and its job form.

The analysis is :func:`pipeflow.stability_spec.run_stability`; the body is
:class:`pipeflow.stability_spec.StabilitySpec`.  ``POST /v1/stability/jobs`` takes the same
body and answers 202 with a job, like ``POST /v1/jobs`` does for simulations: the job id is
the parameter hash, so the sync and async forms share one cache entry.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body
from fastapi.responses import JSONResponse, Response

from pipeflow.stability_spec import PAPER_PIPE_JSON, StabilitySpec
from service.compute import CACHE_HEADERS, JOB_ACCEPTED, Refresh, accept_job, run_sync
from service.deps import HitDep, RunnerDep, StoreDep
from service.kinds import STABILITY
from service.problems import responses
from service.schemas import JobStatus
from service.stability_schemas import StabilityResponse

router = APIRouter(prefix="/v1/stability", tags=["stability"])

#: the paper's pipe (beta = 0.467) at w0 = 100 rad/s: flutter of mode 3 at v = 27.69 m/s
PAPER_STABILITY: dict[str, Any] = {
    "pipe": PAPER_PIPE_JSON,
    "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
    "modes": 10,
    "velocity_range": [0.0, 60.0],
}

StabilityBody = Annotated[
    StabilitySpec,
    Body(
        openapi_examples={
            "paper": {
                "summary": "The paper's pipe at w0 = 100 rad/s, v from 0 to 60 m/s, 10 modes",
                "description": "Flutter of mode 3 at v = 27.69 m/s (u_cr = 9.15).",
                "value": PAPER_STABILITY,
            },
            "reverse_flow": {
                "summary": "A range reaching reverse flow: answered with the aspirating-pipe "
                "caveat",
                "value": {**PAPER_STABILITY, "velocity_range": [-10.0, 60.0]},
            },
        }
    ),
]


@router.post(
    "",
    operation_id="runStability",
    summary="Critical flow velocities at constant spin (or served from the cache)",
    response_model=StabilityResponse,
    responses={200: {"headers": CACHE_HEADERS}, **responses(409, 413, 422, 503)},
)
async def run_stability(
    spec: StabilityBody, runner: RunnerDep, store: StoreDep, hit: HitDep, refresh: Refresh = False
) -> Response:
    """Every crossing of the stability boundary (sigma = 0) for flow velocities v [m/s] in
    ``velocity_range`` at constant spin w0 [rad/s]: flutter or divergence, loss or gain, the
    crossing mode and its frequency [rad/s], each located by root-finding.
    ``critical_velocity`` [m/s] is the first loss (null when stable throughout); the
    non-dimensional u_cr, beta and gamma are in ``dimensionless``.  The v < 0 part of the
    range (reverse flow, the aspirating pipe) gets the caveat in ``reverse_flow`` and no
    threshold.  Cached like simulations (``X-Cache``, ``?refresh=true``)."""
    return await run_sync(runner, store, STABILITY, spec, refresh, hit)


@router.post(
    "/jobs",
    operation_id="submitStabilityJob",
    summary="Submit a critical-velocity analysis as a job",
    status_code=202,
    response_model=JobStatus,
    responses={**JOB_ACCEPTED, **responses(413, 422, 503)},
)
async def submit_stability_job(
    spec: StabilityBody, runner: RunnerDep, store: StoreDep, refresh: Refresh = False
) -> JSONResponse:
    """The same analysis as ``POST /v1/stability``, answered at once with its job (202,
    ``Location: /v1/jobs/{key}``); poll the job, then ``GET /v1/results/{key}``."""
    return await accept_job(runner, store, STABILITY, spec, refresh)
