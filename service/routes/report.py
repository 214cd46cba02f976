"""``GET /v1/results/{key}/report.html`` and ``.pdf``: a stored result's report;
``GET /v1/results/{key}/animations/mode_shapes.gif``: a mode shape in motion.

The document an engineer attaches to a design review (:mod:`pipeflow.io.report`): the
inputs (the request, when the service still holds its job record), the key numbers, the
figures, the method and diagnostics, the warnings and the version.  Drawn in a thread
under the figures' lock (:mod:`service.routes.exports`): matplotlib's rc settings used
while saving are process-global.
"""

from __future__ import annotations

import asyncio
import json
from typing import TYPE_CHECKING, Annotated, Any

from fastapi import APIRouter, Header, Path, Query, Response

from pipeflow.io import animation, report
from pipeflow.io.plots import PlotError
from service.deps import StoreDep
from service.http.problems import ProblemError, responses
from service.http.security import REPORT_CSP
from service.routes.exports import BINARY, _draw_lock, request_pipe, stored
from service.schemas import KEY_PATTERN

if TYPE_CHECKING:
    from pipeflow.model import Pipe

router = APIRouter(prefix="/v1/results", tags=["results"])


def _render(body: bytes, spec: dict[str, Any] | None, key: str, fmt: str) -> bytes:
    result = json.loads(body)
    with _draw_lock:
        if fmt == "pdf":
            return report.to_pdf(result, spec, key)
        return report.to_html(result, spec, key).encode()


#: what both report operations say of their answer
REPORT_DESCRIPTION = (
    "The report: inputs, key numbers (SI units), figures, method and diagnostics, warnings, "
    "the pipeflow version."
)


async def _report(store: StoreDep, key: str, fmt: str, if_none_match: str | None) -> Response:
    """The report of the result stored under ``key`` as ``fmt`` (``html`` or ``pdf``)."""
    headers, body = await stored(store, key, f'"{key}-report.{fmt}"', if_none_match)
    if fmt == "html":  # opened in a browser: its inline styles and data: figures only
        headers["Content-Security-Policy"] = REPORT_CSP
    if body is None:
        return Response(status_code=304, headers=headers)
    job = await asyncio.to_thread(store.get_job, key)
    spec = job.spec if job is not None else None
    data = await asyncio.to_thread(_render, body, spec, key, fmt)
    return Response(data, media_type=report.MEDIA_TYPES[fmt], headers=headers)


# One operation per media type: a generated client reads each answer as what its one media
# type declares (the PDF as bytes).  One operation declaring both made openapi-python-client
# read the PDF as text, and a client saved it corrupt.
@router.get(
    "/{key}/report.html",
    operation_id="getResultReportHtml",
    summary="A report of a stored result (HTML)",
    response_class=Response,
    responses={
        200: {
            "content": {report.MEDIA_TYPES["html"]: {"schema": {"type": "string"}}},
            "description": REPORT_DESCRIPTION,
        },
        **responses(304, 404, 422),
    },
)
async def get_result_report_html(
    key: Annotated[str, Path(pattern=KEY_PATTERN, description="Parameter hash.")],
    store: StoreDep,
    if_none_match: Annotated[str | None, Header()] = None,
) -> Response:
    """The report of the result stored under ``key`` as a self-contained HTML page (figures
    embedded as PNG)."""
    return await _report(store, key, "html", if_none_match)


@router.get(
    "/{key}/report.pdf",
    operation_id="getResultReportPdf",
    summary="A report of a stored result (PDF)",
    response_class=Response,
    responses={
        200: {
            "content": {report.MEDIA_TYPES["pdf"]: {"schema": BINARY}},
            "description": REPORT_DESCRIPTION,
        },
        **responses(304, 404, 422),
    },
)
async def get_result_report_pdf(
    key: Annotated[str, Path(pattern=KEY_PATTERN, description="Parameter hash.")],
    store: StoreDep,
    if_none_match: Annotated[str | None, Header()] = None,
) -> Response:
    """The report of the result stored under ``key`` as a PDF (matplotlib's PdfPages: the
    text, then one figure a page)."""
    return await _report(store, key, "pdf", if_none_match)


def _animate(
    body: bytes, mode: int | None, time_index: int, frames: int, pipe: Pipe | None = None
) -> bytes:
    result = json.loads(body)
    if not (result.get("mode_shapes") or {}).get("modes"):
        raise ProblemError(
            404,
            "this result has no mode shapes; ask output.mode_shapes in the simulation",
            slug="no-such-plot",
        )
    try:
        with _draw_lock:
            return animation.mode_shape_gif(result, mode, time_index, frames, pipe=pipe)
    except PlotError as exc:
        raise ProblemError(
            422,
            exc.message,
            slug="validation",
            errors=[{"field": exc.field, "location": "query", "message": exc.message}],
        ) from None


@router.get(
    "/{key}/animations/mode_shapes.gif",
    operation_id="getResultModeShapeAnimation",
    summary="A complex mode shape of a stored simulation in motion (GIF)",
    response_class=Response,
    responses={
        200: {
            "content": {"image/gif": {"schema": BINARY}},
            "description": "Re(Phi(x) e^(i theta)) [-] against x [m] over one period.",
        },
        **responses(304, 404, 422),
    },
)
async def get_mode_shape_animation(
    key: Annotated[str, Path(pattern=KEY_PATTERN, description="Parameter hash.")],
    store: StoreDep,
    mode: Annotated[
        int | None, Query(ge=1, description="Branch number (default: the first traced).")
    ] = None,
    time_index: Annotated[
        int, Query(ge=0, description="Index into the mode shapes' times t [s].")
    ] = 0,
    frames: Annotated[
        int,
        Query(ge=2, le=animation.MAX_FRAMES, description="Frames of one period [-]."),
    ] = animation.DEFAULT_FRAMES,
    if_none_match: Annotated[str | None, Header()] = None,
) -> Response:
    """The mode shape of branch ``mode`` at mode-shape time ``time_index`` of the stored
    simulation ``key`` moving over one period (a looping GIF; the result must have asked
    ``output.mode_shapes``)."""
    etag = f'"{key}-modes-{mode}-{time_index}-{frames}-supports.gif"'
    headers, body = await stored(store, key, etag, if_none_match)
    if body is None:
        return Response(status_code=304, headers=headers)
    pipe = await asyncio.to_thread(request_pipe, store, key)
    data = await asyncio.to_thread(_animate, body, mode, time_index, frames, pipe)
    return Response(data, media_type="image/gif", headers=headers)
