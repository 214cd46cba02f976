"""POST /v1/simulations: run one simulation and return it."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Response

from pipeflow.spec import PAPER_EXAMPLE, SimulationSpec
from service.compute import CACHE_HEADERS, Refresh, run_sync
from service.deps import HitDep, RunnerDep, StoreDep
from service.kinds import SIMULATION
from service.problems import responses
from service.schemas import SimulationResponse

router = APIRouter(prefix="/v1", tags=["simulations"])

SpecBody = Annotated[
    SimulationSpec,
    Body(
        openapi_examples={
            "paper": {
                "summary": "The paper's section 5: v = 0.4 t m/s, w0 = 100 rad/s, 10 modes, 1 s",
                "value": PAPER_EXAMPLE,
            }
        }
    ),
]


@router.post(
    "/simulations",
    operation_id="runSimulation",
    summary="Run one simulation (or serve it from the cache)",
    response_model=SimulationResponse,
    responses={
        200: {"headers": CACHE_HEADERS},
        **responses(409, 413, 422, 503),
    },
)
async def run_simulation(
    spec: SpecBody, runner: RunnerDep, store: StoreDep, hit: HitDep, refresh: Refresh = False
) -> Response:
    """Validate the spec, then answer with the result: cached if an equivalent request
    (same key) was computed before, otherwise computed in a worker process.  Identical
    concurrent requests share one computation."""
    return await run_sync(runner, store, SIMULATION, spec, refresh, hit)
