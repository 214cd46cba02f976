"""The computing routes, generated from :data:`pipeflow.computations.registry.COMPUTATIONS` and
the service's table of where each is asked for (:data:`service.routes.endpoints.ENDPOINTS`).

Every endpoint gets ``POST /v1/<path>`` (the result, or a job when the
endpoint only runs as jobs) and ``POST /v1/<path>/jobs`` (202 with a job,
``Location: /v1/jobs/{key}``; for an endpoint that only runs as jobs the same operation
under a second path, so that every computation has its ``/jobs``), plus its aliases
(``POST /v1/jobs`` for simulations).  The
body is the computation's request model (a union told apart by ``kind`` where several
computations share the endpoint), validated once by FastAPI in a worker thread
(:class:`service.http.body.ThreadValidatedRoute`) and keyed once, in a thread too
(:func:`service.keys.keyed_in_thread`); the job id is the key, so the sync and job forms share one
cache entry.  Nothing here is written per computation.
"""

# no ``from __future__ import annotations``: the handlers' annotations are built at run time

from collections.abc import Callable
from typing import Annotated, Any

from fastapi import APIRouter, Body, Depends
from fastapi.responses import JSONResponse, Response
from pydantic import BaseModel

from pipeflow.computations.registry import (
    COMPUTATIONS,
    Computation,
    computation_for,
    request_type,
    response_type,
)
from service.deps import HitDep, RunnerDep, StoreDep
from service.http.body import ThreadValidatedRoute, thread_validated
from service.http.identity import principal
from service.http.negotiation import JSON, accepts, json_body
from service.http.problems import responses
from service.http.responses import CACHE_HEADERS, JOB_ACCEPTED
from service.keys import keyed_in_thread
from service.orchestration import Refresh, accept_job, run_sync
from service.routes.endpoints import Endpoint, computations_at
from service.schemas import JobStatus

#: problem documents every computing operation can answer
PROBLEMS = (400, 406, 413, 415, 422, 429, 503)
#: the client identity (quotas, fairness of the job queue)
Principal = Annotated[str, Depends(principal)]
NEGOTIATION = [Depends(json_body), Depends(accepts(JSON))]


def examples(endpoint: Endpoint) -> dict[str, Any]:
    return {
        k: v for name in computations_at(endpoint) for k, v in COMPUTATIONS[name].examples.items()
    }


def cost_note(endpoint: Endpoint) -> str:
    """The cost bound of each computation at ``endpoint``, for the operation's description."""
    lines = [f"- ``{name}``: {COMPUTATIONS[name].cost}" for name in computations_at(endpoint)]
    return "\n\nCost bounds (a request beyond them is a 422 before any work):\n\n" + "\n".join(
        lines
    )


def _computation(endpoint: Endpoint) -> Callable[[BaseModel], Computation]:
    names = computations_at(endpoint)
    if len(names) == 1:
        only = COMPUTATIONS[names[0]]
        return lambda _request: only
    return computation_for


def router_for(endpoint: Endpoint) -> APIRouter:
    """The routes of one endpoint (of :data:`~service.routes.endpoints.ENDPOINTS`)."""
    # the body parsed, validated (service.http.body) and keyed in worker threads
    router = APIRouter(prefix="/v1", tags=[endpoint.tag], route_class=ThreadValidatedRoute)
    kinds = computations_at(endpoint)
    body: Any = Annotated[
        thread_validated(request_type(kinds)), Body(openapi_examples=examples(endpoint))
    ]
    which = _computation(endpoint)

    async def run(
        request: body,
        runner: RunnerDep,
        store: StoreDep,
        hit: HitDep,
        who: Principal,
        refresh: Refresh = False,
    ) -> Response:
        job = await keyed_in_thread(which(request), request)
        return await run_sync(runner, store, job, refresh, hit, who)

    async def submit(
        request: body,
        runner: RunnerDep,
        store: StoreDep,
        who: Principal,
        refresh: Refresh = False,
    ) -> JSONResponse:
        job = await keyed_in_thread(which(request), request)
        return await accept_job(runner, store, job, refresh, who)

    costs = cost_note(endpoint)
    job_description = (
        f"The same computation as ``POST /v1/{endpoint.path}``, answered at once with its job "
        "(202, ``Location: /v1/jobs/{key}``); wait for the job (``GET /v1/jobs/{key}?wait=30``: "
        "a long poll, answered when it has ended), then ``GET /v1/results/{key}``.  "
        "The job id is the parameter hash: resubmitting is idempotent, a finished result is "
        "reused, and a failed or cancelled job is run again." + costs
    )

    def add_job_route(path: str, operation_id: str, description: str) -> None:
        router.add_api_route(
            path,
            submit,
            methods=["POST"],
            operation_id=operation_id,
            summary=endpoint.job_summary,
            description=description,
            status_code=202,
            response_model=JobStatus,
            responses={**JOB_ACCEPTED, **responses(*PROBLEMS)},
            dependencies=NEGOTIATION,
        )

    if endpoint.run_operation is None:  # always a job, at both paths
        add_job_route(f"/{endpoint.path}", endpoint.job_operation, endpoint.description + costs)
        add_job_route(
            f"/{endpoint.path}/jobs",
            f"{endpoint.job_operation}Job",
            f"The same operation as ``POST /v1/{endpoint.path}`` (which always answers with "
            "a job), under the ``/jobs`` path every computation has.  "
            + endpoint.description
            + costs,
        )
        return router
    router.add_api_route(
        f"/{endpoint.path}",
        run,
        methods=["POST"],
        operation_id=endpoint.run_operation,
        summary=endpoint.summary,
        description=endpoint.description + costs,
        response_model=response_type(kinds),
        responses={200: {"headers": CACHE_HEADERS}, **responses(409, *PROBLEMS)},
        dependencies=NEGOTIATION,
    )
    add_job_route(f"/{endpoint.path}/jobs", endpoint.job_operation, job_description)
    for path, operation_id in endpoint.job_aliases:
        add_job_route(
            path.removeprefix("/v1"),
            operation_id,
            f"Alias of ``POST /v1/{endpoint.path}/jobs``.  " + job_description,
        )
    return router
