"""GET /v1/results/{key}: stored results with a strong ETag."""

from __future__ import annotations

import asyncio
from typing import Annotated, Any, Literal, Union

from fastapi import APIRouter, Depends, Header, Path, Query, Response

from pipeflow.export import CSV_MEDIA_TYPE
from pipeflow.schema.registry import COMPUTATIONS
from service.compute import CACHE_HEADERS, result_response
from service.deps import RunnerDep, StoreDep
from service.negotiation import JSON, accepts
from service.problems import ProblemError, responses
from service.routes.exports import TABLE_DESCRIPTION, Table, csv_response, wants_csv
from service.schemas import KEY_PATTERN

router = APIRouter(
    prefix="/v1/results", tags=["results"], dependencies=[Depends(accepts(JSON, CSV_MEDIA_TYPE))]
)

#: what a stored result can be: one model per result shape of the registry
ResultDocument: Any = Union[  # noqa: UP007
    tuple(dict.fromkeys(c.response for c in COMPUTATIONS.values() if c.endpoint is not None))
]


def _matches(if_none_match: str, key: str) -> bool:
    """RFC 9110 If-None-Match: weak comparison against the entity tag ``"<key>"``."""
    tags = [t.strip() for t in if_none_match.split(",")]
    return any(t == "*" or t.removeprefix("W/") == f'"{key}"' for t in tags)


@router.get(
    "/{key}",
    operation_id="getResult",
    summary="A stored result",
    response_model=ResultDocument,
    responses={
        200: {"headers": CACHE_HEADERS, "content": {"text/csv": {}}},
        **responses(304, 404, 406, 422),
    },
)
async def get_result(
    key: Annotated[str, Path(pattern=KEY_PATTERN, description="Parameter hash.")],
    store: StoreDep,
    runner: RunnerDep,
    if_none_match: Annotated[str | None, Header()] = None,
    accept: Annotated[str | None, Header()] = None,
    format: Annotated[
        Literal["json", "csv"] | None,
        Query(description="json or csv; overrides Accept (for clients that cannot set it)."),
    ] = None,
    table: Annotated[Table, Query(description=TABLE_DESCRIPTION)] = "history",
) -> Response:
    """The result stored under ``key`` (as POST /v1/simulations or /v1/stability returned
    it, or the result of a job), with
    ``ETag: "<key>"``; ``If-None-Match`` with that tag is answered 304.  With
    ``Accept: text/csv`` or ``?format=csv``: one CSV ``table`` whose header row names each
    column with its unit, e.g. ``t [s],tip_displacement [m]``."""
    if wants_csv(format, accept):
        body = await asyncio.to_thread(store.get_result, key)
        if body is None:
            raise ProblemError(404, f"no result {key}", slug="unknown-key")
        # parse the stored JSON and write the table off the event loop: results can be MBs
        return await asyncio.to_thread(csv_response, key, body, table)
    if if_none_match is not None and _matches(if_none_match, key):
        if await asyncio.to_thread(store.has_result, key):
            return Response(status_code=304, headers={"ETag": f'"{key}"'})
    body = await asyncio.to_thread(store.get_result, key)
    if body is None:
        pending = " yet; its job is still in progress" if runner.is_active(key) else ""
        raise ProblemError(404, f"no result {key}{pending}", slug="unknown-key")
    return result_response(key, True, body)
