"""The interactive API documentation, offline: Swagger UI at ``/docs``, ReDoc at ``/redoc``.

FastAPI's default pages load Swagger UI and ReDoc from a CDN, so without internet ``/docs``
is blank.  Here both load from assets vendored by the ``fastapi-offline`` package (MIT; it
ships swagger-ui-dist's bundle and ReDoc's standalone build), served under
``/static/docs/`` from a fixed allow-list.  A Content-Security-Policy keeps the pages from
reaching any other origin: Swagger UI's online validator is switched off and ReDoc's
"powered by" logo (fetched from its CDN, hidden when that fails) is not requested at all.
None of these routes is part of the API, so all are left out of the OpenAPI document.
"""

from __future__ import annotations

from pathlib import Path

import fastapi_offline
from fastapi import APIRouter, Request, Response
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html

from service.http.security import DOCS_CSP
from service.routes.assets import AllowList

ASSET_DIR = Path(fastapi_offline.__file__).resolve().parent / "static"

#: file name -> media type of every documentation asset served
ASSETS: dict[str, str] = {
    "swagger-ui-bundle.js": "text/javascript; charset=utf-8",
    "swagger-ui.css": "text/css; charset=utf-8",
    "redoc.standalone.js": "text/javascript; charset=utf-8",
    "favicon.png": "image/png",
}

router = APIRouter(include_in_schema=False)


def _asset_url(request: Request, name: str) -> str:
    return f"{request.scope.get('root_path', '')}/static/docs/{name}"


def _page(html: Response) -> Response:
    html.headers["Content-Security-Policy"] = DOCS_CSP
    html.headers["Cache-Control"] = "no-cache"
    return html


@router.get("/docs")
async def swagger_ui(request: Request) -> Response:
    """Swagger UI over ``/openapi.json``."""
    return _page(
        get_swagger_ui_html(
            openapi_url=f"{request.scope.get('root_path', '')}{request.app.openapi_url}",
            title=f"{request.app.title} - Swagger UI",
            swagger_js_url=_asset_url(request, "swagger-ui-bundle.js"),
            swagger_css_url=_asset_url(request, "swagger-ui.css"),
            swagger_favicon_url=_asset_url(request, "favicon.png"),
            # null: no badge that sends the document to validator.swagger.io
            swagger_ui_parameters={"validatorUrl": None},
        )
    )


@router.get("/redoc")
async def redoc(request: Request) -> Response:
    """ReDoc over ``/openapi.json``."""
    return _page(
        get_redoc_html(
            openapi_url=f"{request.scope.get('root_path', '')}{request.app.openapi_url}",
            title=f"{request.app.title} - ReDoc",
            redoc_js_url=_asset_url(request, "redoc.standalone.js"),
            redoc_favicon_url=_asset_url(request, "favicon.png"),
            with_google_fonts=False,
        )
    )


_FILES = AllowList(ASSET_DIR, ASSETS, "documentation file")


@router.get("/static/docs/{name}")
async def docs_asset(name: str) -> Response:
    """One of the documentation assets (allow-list :data:`ASSETS`)."""
    return _FILES.response(name)
