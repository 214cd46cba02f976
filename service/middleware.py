"""Cross-cutting ASGI middleware."""

from __future__ import annotations

from fastapi import HTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.problems import problem, response


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
