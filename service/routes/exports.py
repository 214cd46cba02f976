"""Stored results as pictures, tables and files: plots (PNG/SVG), CSV, Parquet, UFF, netCDF.

- ``GET /v1/results/{key}/plots/{name}.{fmt}``: a figure of the stored result, drawn by
  :mod:`pipeflow.io.plots` (the names a result supports are listed in its ``plots`` field).
- ``GET /v1/results/{key}/tables/{table}.{fmt}``: a table of the stored result as CSV or
  Parquet, the operation that declares those media types (a generated OpenAPI client reads
  them as bytes; one operation answering both JSON and tables made it parse CSV as JSON).
- CSV or Parquet of ``GET /v1/results/{key}`` (``Accept: text/csv`` /
  ``application/vnd.apache.parquet`` or ``?format=csv|parquet``, kept for curl and the
  Python client, not in that operation's OpenAPI): the route in
  :mod:`service.routes.results` calls :func:`table_response` from here, so one module owns
  the content negotiation and the tables of :mod:`pipeflow.io.export`.  Each table is
  encoded once and kept in the app's :class:`TableCache` (a bounded LRU); ``If-None-Match``
  is answered 304.
- UFF, netCDF or MATLAB of ``GET /v1/results/{key}`` (``?format=uff|netcdf|mat`` or
  ``Accept: application/vnd.uff`` / ``application/x-netcdf`` /
  ``application/x-matlab-data``): the whole result as one file
  (:mod:`pipeflow.io.formats`), encoded and cached like a table.

Drawing happens in a thread (not on the event loop) under a lock: matplotlib's figure
objects are independent, but its rc settings used while saving are process-global.
"""

from __future__ import annotations

import asyncio
import json
import threading
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, Any, Literal

from fastapi import APIRouter, Depends, Header, Path, Query, Request, Response

from pipeflow.io import plots
from pipeflow.io.export import (
    CSV_MEDIA_TYPE,
    PARQUET_MEDIA_TYPE,
    TABLES,
    ExportError,
    available_tables,
    to_csv,
    to_parquet,
)
from pipeflow.io.formats import (
    MAT_MEDIA_TYPE,
    NETCDF_MEDIA_TYPE,
    UFF_MEDIA_TYPE,
    to_mat,
    to_netcdf,
    to_uff,
)
from pipeflow.model import Pipe
from pipeflow.schema.simulation import pipe_of_request
from service.deps import StoreDep
from service.http.negotiation import accepts, media_ranges
from service.http.problems import ProblemError, responses
from service.http.responses import AnswerCache, etag_matches
from service.http.security import SVG_CSP
from service.schemas import KEY_PATTERN
from service.store import Store

router = APIRouter(prefix="/v1/results", tags=["results"])

_draw_lock = threading.Lock()

#: stored results never change under a key (the key hashes the inputs and the version)
IMMUTABLE = "public, max-age=86400, immutable"

#: a binary body in OpenAPI (3.1 reads format "binary" as raw bytes; generated clients return
#: the bytes as a file rather than trying to parse them as JSON)
BINARY = {"type": "string", "format": "binary"}

if TYPE_CHECKING:
    Table = str
else:  # the names of pipeflow.io.export.TABLES (one list), for the query's schema
    Table = Literal[tuple(TABLES)]
TABLE_DESCRIPTION = (
    "CSV/Parquet table (default: the result's first, 'history' for a simulation, 'study' "
    "for a study): " + "; ".join(f"'{k}': {v}" for k, v in TABLES.items())
)
#: format name -> media type of the tables (JSON is the result document itself)
TABLE_MEDIA_TYPES = {"csv": CSV_MEDIA_TYPE, "parquet": PARQUET_MEDIA_TYPE}
#: whole-result files of ``GET /v1/results/{key}?format=``: name -> media type, extension
FILE_FORMATS = {
    "uff": (UFF_MEDIA_TYPE, "uff"),
    "netcdf": (NETCDF_MEDIA_TYPE, "nc"),
    "mat": (MAT_MEDIA_TYPE, "mat"),
}
#: format name -> writer of the whole result
FILE_WRITERS = {"uff": to_uff, "netcdf": to_netcdf, "mat": to_mat}
FILE_MEDIA_TYPES = tuple(media for media, _ in FILE_FORMATS.values())
#: OpenAPI content of a 200 that is a table: bytes (CSV text in UTF-8, binary Parquet)
TABLE_CONTENT: dict[str, Any] = {media: {"schema": BINARY} for media in TABLE_MEDIA_TYPES.values()}


def wants_csv(fmt: str | None, accept: str | None) -> bool:
    """CSV when ``?format=csv``, or when ``Accept`` prefers text/csv over JSON."""
    return wanted_format(fmt, accept) == "csv"


def wanted_format(fmt: str | None, accept: str | None) -> str:
    """``"json"``, ``"csv"`` or ``"parquet"``: ``?format=`` if given, else the media type
    ``Accept`` prefers among JSON, text/csv and application/vnd.apache.parquet."""
    if fmt is not None:
        return fmt
    if not accept:
        return "json"
    ranked = [(q, -i, media) for i, (media, q) in enumerate(media_ranges(accept))]
    by_media = {media: name for name, media in TABLE_MEDIA_TYPES.items()}
    by_media.update({media: name for name, (media, _) in FILE_FORMATS.items()})
    for _, _, media in sorted(ranked, reverse=True):
        if media in by_media:
            return by_media[media]
        if media in ("application/json", "application/*", "*/*", "application/problem+json"):
            return "json"
    return "json"


@dataclass(frozen=True)
class TableAnswer:
    """One table of a stored result, encoded: what a CSV or Parquet answer sends."""

    key: str
    table: str
    fmt: str
    content: bytes

    @property
    def size(self) -> int:
        return len(self.content)

    @property
    def etag(self) -> str:
        """Strong validator: ``"<key>-<table>.<fmt>"`` (the result is immutable per key)."""
        return f'"{self.key}-{self.table}.{self.fmt}"'

    def headers(self) -> dict[str, str]:
        return {"ETag": self.etag, "Cache-Control": IMMUTABLE, "Vary": "Accept"}

    def response(self) -> Response:
        if self.fmt in FILE_FORMATS:
            media, ext = FILE_FORMATS[self.fmt]
            name = f"{self.key[:12]}.{ext}"
        else:
            media = TABLE_MEDIA_TYPES[self.fmt]
            name = f"{self.key[:12]}-{self.table}.{self.fmt}"
        return Response(
            self.content,
            media_type=f"{media}; charset=utf-8; header=present" if self.fmt == "csv" else media,
            headers={
                **self.headers(),
                "Content-Disposition": f'inline; filename="{name}"',
            },
        )


class TableCache(AnswerCache[TableAnswer]):
    """The encoded tables by key, table asked for (empty: the default) and format: a
    repeated download (or an ``If-None-Match`` check) neither reads the store nor parses
    the result nor writes the table again."""


async def get_tables(request: Request) -> TableCache | None:
    """The app's :class:`TableCache` (``app.state.tables``; None: encode every time)."""
    cache: TableCache | None = getattr(request.app.state, "tables", None)
    return cache


TablesDep = Annotated[TableCache | None, Depends(get_tables)]


def encode_table(key: str, body: bytes, table: str | None, fmt: str) -> TableAnswer:
    """Table ``table`` (None: the result's first) of the stored result ``body`` (JSON bytes)
    as ``fmt`` (csv, parquet)."""
    result = json.loads(body)
    if fmt in FILE_FORMATS:
        return _encode_file(key, result, fmt)
    if table is None:
        table = next(iter(available_tables(result)), "history")
    try:
        content: str | bytes = to_csv(result, table) if fmt == "csv" else to_parquet(result, table)
    except ImportError as exc:  # pyarrow is an optional extra of the server
        raise ProblemError(
            406,
            f"{exc}; ask for CSV instead",
            slug="format-unavailable",
            errors=[{"field": "format", "location": "query", "message": str(exc)}],
        ) from None
    except ExportError as exc:
        tables = ", ".join(available_tables(result)) or "none"
        raise ProblemError(
            404 if table in TABLES else 422,
            f"{exc.message} (this result has: {tables})",
            slug="no-such-table",
            errors=[{"field": "table", "location": "query", "message": exc.message}],
        ) from None
    data = content.encode() if isinstance(content, str) else content
    return TableAnswer(key, table, fmt, data)


def _encode_file(key: str, result: dict[str, Any], fmt: str) -> TableAnswer:
    """The whole result as a UFF (frequency responses: dataset 58; mode shapes: 55), netCDF
    or (a state-space result) MATLAB file (:mod:`pipeflow.io.formats`)."""
    try:
        content = FILE_WRITERS[fmt](result)
    except ImportError as exc:  # pyuff / xarray: the optional 'formats' extra
        raise ProblemError(
            406,
            f"{exc}; ask for JSON or CSV instead",
            slug="format-unavailable",
            errors=[{"field": "format", "location": "query", "message": str(exc)}],
        ) from None
    except ExportError as exc:
        raise ProblemError(
            422,
            exc.message,
            slug="format-unavailable",
            errors=[{"field": "format", "location": "query", "message": exc.message}],
        ) from None
    return TableAnswer(key, "result", fmt, content)


async def table_response(
    key: str,
    table: str | None,
    fmt: str,
    store: Store,
    cache: TableCache | None,
    if_none_match: str | None,
) -> Response:
    """The CSV/Parquet answer of ``GET /v1/results/{key}``: from ``cache`` when it holds
    the table, else read, parsed and written off the event loop (results can be MBs) and
    kept; ``If-None-Match`` with the table's ETag is answered 304."""
    slot = f"{key}/{table or ''}.{fmt}"
    answer = cache.get(slot) if cache is not None else None
    if answer is None:
        body = await asyncio.to_thread(store.get_result, key)
        if body is None:
            raise ProblemError(404, f"no result {key}", slug="unknown-key")
        answer = await asyncio.to_thread(encode_table, key, body, table, fmt)
        if cache is not None:
            cache.put(slot, answer)
    if if_none_match is not None and etag_matches(if_none_match, answer.etag):
        return Response(status_code=304, headers=answer.headers())
    return answer.response()


def request_pipe(store: Any, key: str) -> Pipe | None:
    """The pipe of the request stored under ``key`` (the job record's spec), whose supports
    the figures along x draw; None when no record holds it (a result stored without one
    draws no supports).  Blocking: call it in a thread."""
    job = store.get_job(key)
    return None if job is None else pipe_of_request(job.spec)


def _render(
    body: bytes,
    name: str,
    fmt: str,
    units: dict[str, str] | None = None,
    pipe: Pipe | None = None,
) -> bytes:
    result = json.loads(body)
    names = plots.available_plots(result)
    if name not in names:
        raise ProblemError(
            404,
            f"no plot {name!r} for this result; it has: {', '.join(names) or 'none'}",
            slug="no-such-plot",
            errors=[{"field": "name", "location": "path", "message": f"unknown plot {name!r}"}],
        )
    with _draw_lock:
        return plots.render(result, name, fmt, units=units, pipe=pipe)


@router.get(
    "/{key}/plots/{name}.{fmt}",
    operation_id="getResultPlot",
    summary="A figure of a stored result (PNG or SVG)",
    response_class=Response,
    dependencies=[Depends(accepts(*plots.MEDIA_TYPES.values()))],
    responses={
        200: {
            "content": {media: {"schema": BINARY} for media in plots.MEDIA_TYPES.values()},
            "description": "The figure; axis labels carry SI units.",
        },
        **responses(304, 404, 406, 422),
    },
)
async def get_result_plot(
    key: Annotated[str, Path(pattern=KEY_PATTERN, description="Parameter hash.")],
    name: Annotated[
        str,
        Path(
            pattern=r"^[a-z_]+$",
            description="Plot name, one of the result's `plots`: "
            + "; ".join(f"'{k}': {v.title}" for k, v in plots.PLOTS.items()),
        ),
    ],
    fmt: Annotated[Literal["png", "svg"], Path(description="Image format.")],
    store: StoreDep,
    if_none_match: Annotated[str | None, Header()] = None,
    spin_unit: Annotated[
        Literal[tuple(plots.DISPLAY_UNITS["spin"])],  # type: ignore[valid-type]
        Query(description="Unit of the spin axes (Campbell, spin map); the data stay rad/s."),
    ] = "rad/s",
    frequency_unit: Annotated[
        Literal[tuple(plots.DISPLAY_UNITS["frequency"])],  # type: ignore[valid-type]
        Query(description="Unit of the frequency axes (Hz: cycles per second)."),
    ] = "rad/s",
) -> Response:
    """The figure ``name`` of the result stored under ``key``: tip displacement u(L, t) [m],
    damping sigma [1/s] and fundamental frequency omega [rad/s] over t [s] (the paper's three
    kinds of figure), eigenvalue paths (argand) and station displacements."""
    units = {"spin": spin_unit, "frequency": frequency_unit}
    shown = "".join(f"-{u.replace('/', '_')}" for u in units.values() if u != "rad/s")
    along = name in plots.ALONG_PIPE  # these draw the supports (a new picture: a new ETag)
    etag = f'"{key}-{name}{shown}{"-supports" if along else ""}.{fmt}"'
    headers, body = await stored(store, key, etag, if_none_match)
    if fmt == "svg":  # opened on its own, an SVG is a document: its styles only, no script
        headers["Content-Security-Policy"] = SVG_CSP
    if body is None:
        return Response(status_code=304, headers=headers)
    pipe = await asyncio.to_thread(request_pipe, store, key) if along else None
    image = await asyncio.to_thread(_render, body, name, fmt, units, pipe)
    return Response(image, media_type=plots.MEDIA_TYPES[fmt], headers=headers)


async def stored(
    store: Any, key: str, etag: str, if_none_match: str | None
) -> tuple[dict[str, str], bytes | None]:
    """The caching headers of a drawing of the stored result ``key`` (``etag``: what is
    drawn) and the result's bytes, or None when ``If-None-Match`` holds ``etag`` and the
    result is stored (answer 304); a 404 problem when there is no such result.  One
    rule for every picture and document drawn from a stored result."""
    headers = {"ETag": etag, "Cache-Control": IMMUTABLE}
    if if_none_match is not None and etag_matches(if_none_match, etag):
        if await asyncio.to_thread(store.has_result, key):
            return headers, None
    body = await asyncio.to_thread(store.get_result, key)
    if body is None:
        raise ProblemError(404, f"no result {key}", slug="unknown-key")
    return headers, body


@router.get(
    "/{key}/tables/{table}.{fmt}",
    operation_id="getResultTable",
    summary="A table of a stored result (CSV or Parquet)",
    response_class=Response,
    dependencies=[Depends(accepts(*TABLE_MEDIA_TYPES.values()))],
    responses={
        200: {
            "content": TABLE_CONTENT,
            "description": "The table: CSV with a header row naming each column with its SI "
            "unit (`t [s],tip_displacement [m]`), or Parquet with float64 columns named "
            "without units and each unit in the field metadata (`unit`).",
        },
        **responses(404, 406, 422),
    },
)
async def get_result_table(
    key: Annotated[str, Path(pattern=KEY_PATTERN, description="Parameter hash.")],
    table: Annotated[Table, Path(description=TABLE_DESCRIPTION)],
    fmt: Annotated[Literal["csv", "parquet"], Path(description="Table format.")],
    store: StoreDep,
    tables: TablesDep,
    if_none_match: Annotated[str | None, Header()] = None,
) -> Response:
    """Table ``table`` of the result stored under ``key`` as CSV (``text/csv``) or Parquet
    (``application/vnd.apache.parquet``; the server needs pyarrow, else 406 naming the
    extra): the same tables as ``GET /v1/results/{key}?format=...&table=...``, with the
    same ETag (``If-None-Match`` answers 304)."""
    return await table_response(key, table, fmt, store, tables, if_none_match)
