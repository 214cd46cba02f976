"""GET /v1/results/{key}: stored results with a strong ETag."""

from __future__ import annotations

import asyncio
from typing import Annotated, Any, Literal, Union

from fastapi import APIRouter, Depends, Header, Path, Query, Response

from service.deps import HitDep, RunnerDep, StoreDep
from service.http.negotiation import JSON, accepts
from service.http.problems import ProblemError, responses
from service.http.responses import (
    CACHE_HEADERS,
    encoded_hit,
    entity_tag,
    etag_matches,
    result_response,
    sends_gzip,
)
from service.routes.endpoints import served
from service.routes.exports import (
    FILE_MEDIA_TYPES,
    TABLE_DESCRIPTION,
    TABLE_MEDIA_TYPES,
    Table,
    TablesDep,
    table_response,
    wanted_format,
)
from service.schemas import KEY_PATTERN

router = APIRouter(
    prefix="/v1/results",
    tags=["results"],
    dependencies=[Depends(accepts(JSON, *TABLE_MEDIA_TYPES.values(), *FILE_MEDIA_TYPES))],
)

#: what a stored result can be: one model per result shape of the registry
ResultDocument: Any = Union[  # noqa: UP007
    tuple(dict.fromkeys(c.response for c in served()))
]


@router.get(
    "/{key}",
    operation_id="getResult",
    summary="A stored result",
    response_model=ResultDocument,
    responses={200: {"headers": CACHE_HEADERS}, **responses(304, 404, 406, 422)},
)
async def get_result(
    key: Annotated[str, Path(pattern=KEY_PATTERN, description="Parameter hash.")],
    store: StoreDep,
    runner: RunnerDep,
    hit: HitDep,
    tables: TablesDep,
    if_none_match: Annotated[str | None, Header()] = None,
    # content negotiation, not a parameter: the 200's media types document it
    accept: Annotated[str | None, Header(include_in_schema=False)] = None,
    # CSV and Parquet: getResultTable declares them (kept here for curl and pipeflow_client,
    # out of this JSON operation's schema, whose generated client parses every 200 as JSON)
    format: Annotated[
        Literal["json", "csv", "parquet", "uff", "netcdf", "mat"] | None,
        Query(
            description="json, csv, parquet, uff (frequency responses: dataset 58, mode "
            "shapes: 55), netcdf or mat (a state-space result); overrides Accept (for "
            "clients that cannot set it).",
            include_in_schema=False,
        ),
    ] = None,
    table: Annotated[
        Table | None, Query(description=TABLE_DESCRIPTION, include_in_schema=False)
    ] = None,
) -> Response:
    """The result stored under ``key`` (as POST /v1/simulations or /v1/stability returned
    it, or the result of a job), with
    ``ETag: "<key>"`` (``"<key>-gzip"`` for its gzip, sent when ``Accept-Encoding``
    allows); ``If-None-Match`` with the tag of the representation the request selects is
    answered 304 with that tag.  With
    ``Accept: text/csv`` or ``?format=csv``: one CSV ``table`` whose header row names each
    column with its unit, e.g. ``t [s],tip_displacement [m]``.  With
    ``Accept: application/vnd.apache.parquet`` or ``?format=parquet``: the same table as
    Parquet, float64 columns named without units and each unit in the field metadata
    (the operation ``getResultTable``, ``/v1/results/{key}/tables/{table}.{fmt}``, is the
    one that declares those media types).  ``?format=uff``: a universal file (dataset 58
    per operating point and position of a frequency response, abscissa in Hz; dataset 55
    for mode shapes); ``?format=netcdf``: the result as a netCDF-3 file (xarray layout);
    ``?format=mat``: a state-space result as a MATLAB file (A, B, C, D, names, units)."""
    fmt = wanted_format(format, accept)
    if fmt != "json":
        return await table_response(key, table, fmt, store, tables, if_none_match)
    encoded = hit.cache.get(key) if hit.cache is not None else None
    if encoded is None:
        body = await asyncio.to_thread(store.get_result, key)
        if body is None:
            # with keys required, whether someone's job computes it is not said: the job
            # is another client's business (service.http.access)
            running = runner.is_active(key) and not runner.settings.auth_required
            pending = " yet; its job is still in progress" if running else ""
            raise ProblemError(404, f"no result {key}{pending}", slug="unknown-key")
        encoded = await encoded_hit(key, body, hit)
    etag = entity_tag(key, sends_gzip(encoded, hit.gzip))
    if if_none_match is not None and etag_matches(if_none_match, etag):
        return Response(status_code=304, headers={"ETag": etag, "Vary": "Accept-Encoding"})
    return result_response(key, True, encoded, hit.gzip)
