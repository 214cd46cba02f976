"""The browser viewer at ``/``, ``/stability``, ``/frequency-response`` and ``/studies``, and
their static assets under ``/static/``.

``/`` (``service/static/index.html``): a simulation form generated at run time from this
service's ``/openapi.json`` (``schemaform.js``: every method, profile kind and default the
request schema has), a run button calling ``POST /v1/simulations``, uPlot charts and a
banner for unstable runs.  ``/stability`` (``stability.html``): the same kind of form for
``POST /v1/stability`` and every ``POST /v1/sweeps`` kind, job progress, crossing tables and
the server's figures.  ``/frequency-response`` (``frequency.html``): the form of
``POST /v1/frequency-responses``, uPlot charts of |H| (log-log, peaks marked) and the phase,
a table of the peaks and the server's figures.  ``/studies`` (``studies.html``): the form of
``POST /v1/studies`` (cases, grid or sampled parameters), the job's progress, the first rows
of the table with its CSV/Parquet links, a histogram per numeric summary column with the mean
and the 5/50/95 % quantiles marked, the probability of instability, and for saltelli studies
the Sobol' indices S1 and ST per parameter with their confidence intervals.  What the pages
share (job polling with progress, share links, the examples chooser, tables, figures, error
display) is ``pages.js``, loaded after ``schemaform.js`` and before each page's script.  The chart
library is vendored (``service/static/uPlot.iife.min.js``, MIT, from the npm package
``uplot``), so the viewer works without internet access.  The assets are a fixed
allow-list read from the package directory: no path from the request reaches the file
system.  Neither route is part of the API, so both are left out of the OpenAPI document.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, Response

from service.http.security import PAGE_CSP
from service.routes.assets import AllowList

STATIC_DIR = Path(__file__).resolve().parent.parent / "static"

#: file name -> media type of every asset served
ASSETS: dict[str, str] = {
    "viewer.js": "text/javascript; charset=utf-8",
    "schemaform.js": "text/javascript; charset=utf-8",
    "pages.js": "text/javascript; charset=utf-8",
    "stability.js": "text/javascript; charset=utf-8",
    "frequency.js": "text/javascript; charset=utf-8",
    "studies.js": "text/javascript; charset=utf-8",
    "viewer.css": "text/css; charset=utf-8",
    "uPlot.iife.min.js": "text/javascript; charset=utf-8",
    "uPlot.min.css": "text/css; charset=utf-8",
    "uPlot.LICENSE": "text/plain; charset=utf-8",
}

router = APIRouter(include_in_schema=False)

#: the headers of each page (its Content-Security-Policy: :mod:`service.http.security`)
PAGE_HEADERS = {"Cache-Control": "no-cache", "Content-Security-Policy": PAGE_CSP}


#: the assets, and the two pages (read through the same cache, served by their routes)
_FILES = AllowList(STATIC_DIR, ASSETS, "static file")


@router.get("/")
async def viewer_page() -> Response:
    """The viewer page."""
    return Response(
        _FILES.read("index.html"),
        media_type="text/html; charset=utf-8",
        headers=PAGE_HEADERS,
    )


@router.get("/stability")
async def stability_page() -> Response:
    """The stability page (critical velocities, sweeps, maps)."""
    return Response(
        _FILES.read("stability.html"),
        media_type="text/html; charset=utf-8",
        headers=PAGE_HEADERS,
    )


@router.get("/frequency-response")
async def frequency_page() -> Response:
    """The frequency-response page (Bode charts with the peaks, peaks table, figures)."""
    return Response(
        _FILES.read("frequency.html"),
        media_type="text/html; charset=utf-8",
        headers=PAGE_HEADERS,
    )


@router.get("/studies")
async def studies_page() -> Response:
    """The design-study page (table, histograms, instability, Sobol' indices)."""
    return Response(
        _FILES.read("studies.html"),
        media_type="text/html; charset=utf-8",
        headers=PAGE_HEADERS,
    )


@router.get("/static/{name}")
async def viewer_asset(name: str) -> Response:
    """One of the viewer's assets (allow-list :data:`ASSETS`)."""
    return _FILES.response(name)
