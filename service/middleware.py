"""Cross-cutting ASGI middleware."""

from __future__ import annotations

import logging
import re
import time
from typing import Any

from fastapi import HTTPException
from starlette.datastructures import MutableHeaders
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service import observability
from service.problems import problem, response

access_log = logging.getLogger("service.access")
#: the key at the start of a result's ETag (``"<key>"``, ``"<key>-gzip"``, ``"<key>-t.csv"``)
_TAGGED_KEY = re.compile(r'(?:W/)?"([0-9a-f]{64})')


class BodyLimit:
    """Answer 413 to request bodies larger than ``max_bytes``.

    A declared Content-Length is checked before anything is read; a chunked body is
    counted as it streams and stopped at the limit.
    """

    def __init__(self, app: ASGIApp, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        declared = headers.get(b"content-length")
        if declared is not None:
            try:
                size = int(declared)
            except ValueError:
                size = -1
            if size < 0 or size > self.max_bytes:
                status = 400 if size < 0 else 413
                detail = (
                    "invalid Content-Length"
                    if size < 0
                    else f"the body has {size} bytes; the limit is {self.max_bytes} bytes"
                )
                await response(problem(status, detail, instance=scope.get("path")))(
                    scope, receive, send
                )
                return
        seen = 0
        limit = self.max_bytes

        async def limited() -> Message:
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > limit:
                    # FastAPI re-raises HTTPException from body parsing; the problem handler
                    # turns it into problem+json
                    raise HTTPException(413, f"the body exceeds the limit of {limit} bytes")
            return message

        await self.app(scope, limited, send)


class RequestContext:
    """Request id, one log line and the HTTP metrics per request (outermost middleware).

    ``X-Request-ID`` is taken from the request (a token of at most 128 characters) or
    generated, set in :data:`service.observability.REQUEST_ID` for everything the request
    runs, and echoed in the response.  When the response is sent: the request is counted
    and timed under its route TEMPLATE (``/v1/results/{key}``, never the raw path, so the
    label set stays bounded; ``<unmatched>`` when no route matched), its ``X-Cache`` answer
    counted, and a ``request`` log line written with method, route, path, status,
    duration_ms, cache, key and request_id.
    """

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        start = time.perf_counter()
        incoming = next((v for k, v in scope["headers"] if k == b"x-request-id"), None)
        rid = observability.accept_request_id(
            incoming.decode("latin-1") if incoming is not None else None
        )
        token = observability.REQUEST_ID.set(rid)
        seen: dict[str, Any] = {"status": 500, "cache": None, "etag": None}

        async def send_with_id(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = MutableHeaders(scope=message)
                headers["X-Request-ID"] = rid
                seen["status"] = message["status"]
                seen["cache"] = headers.get("x-cache")
                seen["etag"] = headers.get("etag")
            await send(message)

        span = observability.span(
            f"{scope['method']} {scope['path']}",
            {"http.method": scope["method"], "http.target": scope["path"], "request_id": rid},
        )
        try:
            if span is None:
                await self.app(scope, receive, send_with_id)
            else:
                with span:
                    await self.app(scope, receive, send_with_id)
        finally:
            seconds = time.perf_counter() - start
            route = scope.get("route")
            template = getattr(route, "path", None) or "<unmatched>"
            etag = seen["etag"]
            tagged = _TAGGED_KEY.match(etag) if etag else None
            key = tagged.group(1) if tagged else (scope.get("path_params") or {}).get("key")
            observability.record_request(
                template, scope["method"], seen["status"], seconds, seen["cache"]
            )
            access_log.info(
                "request",
                extra={
                    "method": scope["method"],
                    "route": template,
                    "path": scope["path"],
                    "status": seen["status"],
                    "duration_ms": round(seconds * 1e3, 3),
                    "cache": seen["cache"],
                    "key": key,
                },
            )
            observability.REQUEST_ID.reset(token)
