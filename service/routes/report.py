"""``GET /v1/results/{key}/report.html`` and ``.pdf``: a stored result's report.

The document an engineer attaches to a design review (:mod:`pipeflow.io.report`): the
inputs (the request, when the service still holds its job record), the key numbers, the
figures, the method and diagnostics, the warnings and the version.  Drawn in a thread
under the figures' lock (:mod:`service.routes.exports`): matplotlib's rc settings used
while saving are process-global.
"""

from __future__ import annotations

import asyncio
import json
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Header, Path, Response

from pipeflow.io import report
from service.deps import StoreDep
from service.http.problems import ProblemError, responses
from service.routes.exports import BINARY, IMMUTABLE, _draw_lock
from service.schemas import KEY_PATTERN

router = APIRouter(prefix="/v1/results", tags=["results"])


def _render(body: bytes, spec: dict[str, Any] | None, key: str, fmt: str) -> bytes:
    result = json.loads(body)
    with _draw_lock:
        if fmt == "pdf":
            return report.to_pdf(result, spec, key)
        return report.to_html(result, spec, key).encode()


@router.get(
    "/{key}/report.{fmt}",
    operation_id="getResultReport",
    summary="A report of a stored result (HTML or PDF)",
    response_class=Response,
    responses={
        200: {
            "content": {
                report.MEDIA_TYPES["html"]: {"schema": {"type": "string"}},
                report.MEDIA_TYPES["pdf"]: {"schema": BINARY},
            },
            "description": "The report: inputs, key numbers (SI units), figures, method and "
            "diagnostics, warnings, the pipeflow version.",
        },
        **responses(304, 404, 422),
    },
)
async def get_result_report(
    key: Annotated[str, Path(pattern=KEY_PATTERN, description="Parameter hash.")],
    fmt: Annotated[Literal["html", "pdf"], Path(description="Report format.")],
    store: StoreDep,
    if_none_match: Annotated[str | None, Header()] = None,
) -> Response:
    """The report of the result stored under ``key``: a self-contained HTML page (figures
    embedded as PNG) or a PDF (matplotlib's PdfPages: the text, then one figure a page)."""
    etag = f'"{key}-report.{fmt}"'
    headers = {"ETag": etag, "Cache-Control": IMMUTABLE}
    if if_none_match is not None and etag in (t.strip() for t in if_none_match.split(",")):
        if await asyncio.to_thread(store.has_result, key):
            return Response(status_code=304, headers=headers)
    body = await asyncio.to_thread(store.get_result, key)
    if body is None:
        raise ProblemError(404, f"no result {key}", slug="unknown-key")
    job = await asyncio.to_thread(store.get_job, key)
    spec = job.spec if job is not None else None
    data = await asyncio.to_thread(_render, body, spec, key, fmt)
    return Response(data, media_type=report.MEDIA_TYPES[fmt], headers=headers)
