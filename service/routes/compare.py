"""POST /v1/compare: one case, several methods, their cost and their agreement.

The user's own version of the paper's Tables 1 and 2 (CMA against RK4 CPU time): the
computation is :func:`pipeflow.compare.run_compare`; results are cached by parameter hash
like simulations (the timings are those of the run that filled the cache: ``X-Cache``
says which).
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body
from fastapi.responses import Response

from pipeflow.compare import CompareSpec
from pipeflow.spec import PAPER_EXAMPLE
from service.compute import CACHE_HEADERS, Refresh, run_sync
from service.deps import HitDep, RunnerDep, StoreDep
from service.kinds import COMPARE
from service.problems import responses
from service.schemas import CompareResponse

router = APIRouter(prefix="/v1", tags=["compare"])

CompareBody = Annotated[
    CompareSpec,
    Body(
        openapi_examples={
            "paper": {
                "summary": "The paper's v = 0.4 t case with cma, magnus and rk4",
                "value": {"simulation": PAPER_EXAMPLE, "methods": ["cma", "magnus", "rk4"]},
            }
        }
    ),
]


@router.post(
    "/compare",
    operation_id="compareMethods",
    summary="Run one case with several methods; wall times and differences",
    response_model=CompareResponse,
    responses={200: {"headers": CACHE_HEADERS}, **responses(409, 413, 422, 503)},
)
async def compare_methods(
    spec: CompareBody, runner: RunnerDep, store: StoreDep, hit: HitDep, refresh: Refresh = False
) -> Response:
    """Run ``simulation`` with each of ``methods``; for each, the solve and wall time [s],
    the speed-up against the slowest, its estimated relative error [-] and its relative
    difference from the most accurate method (``baseline``) on the modal state and on the
    tip displacement [-]."""
    return await run_sync(runner, store, COMPARE, spec, refresh, hit)
