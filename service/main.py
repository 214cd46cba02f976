"""The ASGI application: ``uvicorn service.main:app``.

:func:`create_app` builds the app from :class:`~service.settings.Settings` (environment
variables ``PIPEFLOW_*``); the module-level ``app`` uses the environment's settings.
"""

from __future__ import annotations

import asyncio
import inspect
import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi

from pipeflow import __version__
from service import observability
from service.engine import Runner, preload
from service.http import auth, problems
from service.http.middleware import BodyLimit, ContentDecoding, HitFastPath, RequestContext
from service.http.responses import HitCache
from service.http.security import SecurityHeaders
from service.routes import (
    computations,
    docs,
    exports,
    health,
    jobs,
    metrics,
    report,
    results,
    viewer,
)
from service.routes.endpoints import endpoints
from service.settings import Settings, get_settings
from service.store import Store, StoreRefused

log = logging.getLogger("service")

#: a body without Content-Type is read as JSON (the README; the hit fast path and
#: :func:`service.http.negotiation.json_declared` do): FastAPI releases that have
#: ``strict_content_type`` refuse such a body as not JSON unless told otherwise
LENIENT_CONTENT_TYPE: dict[str, Any] = (
    {"strict_content_type": False}
    if "strict_content_type" in inspect.signature(FastAPI.__init__).parameters
    else {}
)

#: the OpenAPI document's title.  Client generators name their package after it:
#: openapi-python-client makes ``pipeflow_api_client`` of it (``<title>-client``), which does
#: not shadow this repository's own ``pipeflow_client`` (the title "pipeflow" did); the
#: committed configuration openapi/openapi-python-client.yml names the same package
TITLE = "pipeflow API"

DESCRIPTION = """\
Vibration of a rotating cantilevered pipe conveying fluid with time-varying flow
velocity v(t) [m/s] and spin w0(t) [rad/s] (Wang & Zhong, CMES 114(1), 2018).
SI units throughout. Results are cached by the parameter hash `key`; errors are
RFC 9457 `application/problem+json`.
"""


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the service; ``settings`` defaults to the environment's."""
    settings = settings or get_settings()
    observability.configure_logging(settings.log_level, settings.log_format)
    preload.cap_malloc_arenas()  # before the process starts its threads

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        if settings.database_url is None:
            settings.ensure_data_dir()  # the SQLite file lives there
        try:
            store = await asyncio.to_thread(
                Store, settings.db_url, settings.cache_max_bytes, settings.memory_cache_bytes
            )
        except StoreRefused as exc:
            log.critical("refusing to start: %s", exc)
            raise
        runner = Runner(settings, store)
        app.state.store = store
        app.state.runner = runner
        await runner.start()
        try:
            yield
        finally:
            await runner.stop()
            await asyncio.to_thread(store.close)
            observability.process_exited()

    app = FastAPI(
        title=TITLE,
        version=__version__,
        description=DESCRIPTION,
        lifespan=lifespan,
        docs_url=None,  # served offline by service.routes.docs
        redoc_url=None,
        **LENIENT_CONTENT_TYPE,
    )
    app.state.settings = settings
    app.state.hits = HitCache(settings.hit_cache_bytes)
    app.state.tables = exports.TableCache(settings.table_cache_bytes)
    app.add_middleware(BodyLimit, max_bytes=settings.max_body_bytes)
    # repeated hits are answered here, before body parsing and dependency resolution
    result_paths = frozenset(f"/v1/{e.path}" for e in endpoints() if e.run_operation is not None)
    app.add_middleware(HitFastPath, hits=app.state.hits, paths=result_paths)
    # outside the fast path: a body of a coding it cannot read is refused, gzip inflated
    app.add_middleware(ContentDecoding, max_bytes=settings.max_body_bytes)
    # outside the fast path, so that a hit needs a key too (when keys are required)
    ring = auth.KeyRing.from_settings(settings)  # refuses to start on a bad key ring
    app.add_middleware(auth.Authenticate, settings=settings, ring=ring)
    app.add_middleware(RequestContext)  # 413s and 401s get a request id and a log line too
    app.add_middleware(SecurityHeaders)  # outermost: every answer carries the headers
    problems.install(app)
    for endpoint in endpoints():
        app.include_router(computations.router_for(endpoint))
    for module in (jobs, results, exports, report, health, metrics, docs, viewer):
        app.include_router(module.router)

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            app.openapi_schema = auth.document(
                _problem_media_types(
                    get_openapi(
                        title=app.title,
                        version=app.version,
                        description=app.description,
                        routes=app.routes,
                    )
                ),
                settings,
            )
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
    return app


def _problem_media_types(doc: dict[str, Any]) -> dict[str, Any]:
    """Error responses are application/problem+json; every operation may answer 500."""
    internal = {
        "description": "Internal error (a bug, never bad input).",
        "content": {
            problems.PROBLEM_MEDIA_TYPE: {"schema": {"$ref": "#/components/schemas/Problem"}}
        },
    }
    for path in doc.get("paths", {}).values():
        for operation in path.values():
            operation.setdefault("responses", {}).setdefault("500", internal)
            for code, resp in operation.get("responses", {}).items():
                content = resp.get("content")
                is_error = code.isdigit() and int(code) >= 400
                if is_error and content and "application/json" in content:
                    content[problems.PROBLEM_MEDIA_TYPE] = content.pop("application/json")
    return doc


app = create_app()
