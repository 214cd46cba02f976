"""Cross-cutting ASGI middleware."""

from __future__ import annotations

import hashlib
import logging
import re
import time
import zlib
from collections import OrderedDict
from typing import Any

from fastapi import HTTPException
from starlette.datastructures import MutableHeaders
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service import observability
from service.http import negotiation
from service.http.negotiation import JSON, accepts_gzip
from service.http.problems import internal_problem, problem, response
from service.http.responses import result_response

access_log = logging.getLogger("service.access")
log = logging.getLogger("service")
#: the key at the start of a result's ETag (``"<key>"``, ``"<key>-gzip"``, ``"<key>-t.csv"``)
_TAGGED_KEY = re.compile(r'(?:W/)?"([0-9a-f]{64})')
#: Content-Location of a result answer
_RESULT_LOCATION = re.compile(r"/v1/results/([0-9a-f]{64})")


class HttpMiddleware:
    """An ASGI middleware acting on HTTP requests (:meth:`http`); anything else (the
    lifespan) passes through unchanged."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        await self.http(scope, receive, send)

    async def http(self, scope: Scope, receive: Receive, send: Send) -> None:
        raise NotImplementedError


class BodyLimit(HttpMiddleware):
    """Answer 413 to request bodies larger than ``max_bytes``.

    A declared Content-Length is checked before anything is read; a chunked body is
    counted as it streams and stopped at the limit.
    """

    def __init__(self, app: ASGIApp, max_bytes: int) -> None:
        super().__init__(app)
        self.max_bytes = max_bytes

    async def http(self, scope: Scope, receive: Receive, send: Send) -> None:
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


#: the content codings a request body may have (RFC 9110 section 8.4.1; x-gzip is gzip)
REQUEST_CODINGS = ("gzip", "identity")


class ContentDecoding(HttpMiddleware):
    """Request bodies by their ``Content-Encoding``: ``identity`` (or none) as they are;
    ``gzip`` (``x-gzip``) decompressed as they stream, to at most ``max_bytes`` (413
    beyond: a small body that inflates is no way past the limit), a stream that is not
    gzip or ends early answered 400; any other coding, or several, 415 with
    ``Accept-Encoding: gzip, identity`` (RFC 9110 section 15.5.16).  Requests without a
    body are not looked at.  Outside the hit fast path, which thus never answers a body
    it could not read; the decompressed body has no Content-Length, so the fast path
    leaves it to the route."""

    def __init__(self, app: ASGIApp, max_bytes: int) -> None:
        super().__init__(app)
        self.max_bytes = max_bytes

    async def http(self, scope: Scope, receive: Receive, send: Send) -> None:
        headers = scope.get("headers") or []
        values = [v.decode("latin-1") for k, v in headers if k == b"content-encoding"]
        codings = [c.strip().lower() for v in values for c in v.split(",") if c.strip()]
        codings = [c for c in codings if c != "identity"]
        length = next((v for k, v in headers if k == b"content-length"), None)
        has_body = length not in (None, b"0") or any(k == b"transfer-encoding" for k, _ in headers)
        if not codings or not has_body:
            await self.app(scope, receive, send)
            return
        if length is not None and length.isdigit() and int(length) > self.max_bytes:
            detail = f"the body has {int(length)} bytes; the limit is {self.max_bytes} bytes"
            await response(problem(413, detail, instance=scope.get("path")))(scope, receive, send)
            return
        if codings not in (["gzip"], ["x-gzip"]):
            given = ", ".join(values)
            doc = problem(
                415,
                f"Content-Encoding {given!r} is not supported: send the body as it is "
                "(identity) or gzip",
                slug="unsupported-content-encoding",
                errors=[
                    {
                        "field": "Content-Encoding",
                        "location": "header",
                        "message": "not gzip or identity",
                    }
                ],
                instance=scope.get("path"),
            )
            accepted = {"Accept-Encoding": ", ".join(REQUEST_CODINGS)}
            await response(doc, accepted)(scope, receive, send)
            return
        # the decompressed body: no Content-Encoding, no Content-Length (not known yet)
        inner = dict(scope)
        inner["headers"] = [
            (k, v) for k, v in headers if k not in (b"content-encoding", b"content-length")
        ]
        await self.app(inner, _Gunzip(receive, self.max_bytes).receive, send)


class _Gunzip:
    """The ``receive`` of a gzip request body, decompressed (:class:`ContentDecoding`)."""

    def __init__(self, receive: Receive, max_bytes: int) -> None:
        self._receive = receive
        self.room = max_bytes  # output bytes still allowed
        self.limit = max_bytes
        self.wire = 0
        self._inflate = zlib.decompressobj(16 + zlib.MAX_WBITS)
        self._done = False

    def _out(self, data: bytes) -> bytes:
        """``data`` decompressed (gzip members one after another), within the limit."""
        out = []
        while data:
            chunk = self._inflate.decompress(data, self.room + 1)
            self.room -= len(chunk)
            if self.room < 0:
                raise HTTPException(
                    413, f"the decompressed body exceeds the limit of {self.limit} bytes"
                )
            out.append(chunk)
            if self._inflate.unconsumed_tail:  # room + 1 bytes out: the next call says
                data = self._inflate.unconsumed_tail
            elif self._inflate.eof and self._inflate.unused_data:  # another member
                data = self._inflate.unused_data
                self._inflate = zlib.decompressobj(16 + zlib.MAX_WBITS)
            else:
                data = b""
        return b"".join(out)

    async def receive(self) -> Message:
        message = await self._receive()
        if message["type"] != "http.request" or self._done:
            return message
        data = message.get("body", b"")
        self.wire += len(data)
        if self.wire > self.limit:
            raise HTTPException(413, f"the body exceeds the limit of {self.limit} bytes")
        try:
            body = self._out(data)
        except zlib.error as exc:
            raise HTTPException(400, f"the body is not valid gzip ({exc})") from None
        more = message.get("more_body", False)
        if not more:
            self._done = True
            if not self._inflate.eof:
                raise HTTPException(400, "the body is not valid gzip (it ends early)")
        return {"type": "http.request", "body": body, "more_body": more}


class RequestContext(HttpMiddleware):
    """Request id, one log line and the HTTP metrics per request (outermost middleware).

    ``X-Request-ID`` is taken from the request (a token of at most 128 characters) or
    generated, set in :data:`service.observability.REQUEST_ID` for everything the request
    runs, and echoed in the response.  When the response is sent: the request is counted
    and timed under its route TEMPLATE (``/v1/results/{key}``, never the raw path, so the
    label set stays bounded; ``<unmatched>`` when no route matched), its ``X-Cache`` answer
    counted, and a ``request`` log line written with method, route, path, status,
    duration_ms, cache, key, principal (the API key's id, when authentication is on) and
    request_id.  An exception nothing handled is logged with its traceback and answered
    500 with :func:`service.http.problems.internal_problem` (the request id, not the text).
    """

    async def http(self, scope: Scope, receive: Receive, send: Send) -> None:
        start = time.perf_counter()
        incoming = next((v for k, v in scope["headers"] if k == b"x-request-id"), None)
        rid = observability.accept_request_id(
            incoming.decode("latin-1") if incoming is not None else None
        )
        token = observability.REQUEST_ID.set(rid)
        seen: dict[str, Any] = {"status": 500, "cache": None, "etag": None, "started": False}

        async def send_with_id(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = MutableHeaders(scope=message)
                headers["X-Request-ID"] = rid
                seen["status"] = message["status"]
                seen["started"] = True
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
        except Exception:
            # a bug: the text goes to the log (with the request id), the client gets the id
            log.exception("unhandled error on %s %s", scope["method"], scope["path"])
            if not seen["started"]:
                doc = internal_problem(scope.get("path"))
                await response(doc)(scope, receive, send_with_id)
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
                    "principal": (scope.get("state") or {}).get("principal"),
                },
            )
            observability.REQUEST_ID.reset(token)


#: request bodies the hit fast path reads and remembers [bytes]; larger ones take the route
FAST_BODY_MAX = 64 * 1024
#: bound on the fast path's memo of body digests [entries]
FAST_MEMO_SIZE = 16384


class HitFastPath:
    """Answer a repeated cache hit of a computing route before FastAPI runs.

    A ``POST`` to one of ``paths`` (the registry's result routes) without a query string
    (so no ``refresh``), with a JSON body (:func:`service.http.negotiation.json_declared`), an
    ``Accept`` that admits JSON and a declared Content-Length of at most
    :data:`FAST_BODY_MAX` bytes is read whole.  The SHA-256 of its bytes (with the path)
    looks up the key that the route computed for the same bytes before; if the app's
    :class:`~service.http.responses.HitCache` holds that key's answer, it is sent as the route
    would send it (:func:`service.http.responses.result_response`), without parsing, validating
    or keying the body again.  Anything else (first sight of a body, a miss, an error,
    another route) goes to the app with the body replayed, and a 200 result answer
    teaches the memo its key (``Content-Location: /v1/results/<key>``).

    Sound because the key is a function of the body's bytes alone (the route parses and
    validates them, then hashes the normal form with the version; the same bytes always
    give the same key in one process), and the hit cache holds only answers of stored,
    immutable results.  Inside :class:`RequestContext`, so the request id, the log line
    and the metrics (under the route's template) are the same for both paths.
    """

    def __init__(self, app: ASGIApp, hits: Any, paths: frozenset[str]) -> None:
        self.app = app
        self.hits = hits
        self.paths = paths
        self._memo: OrderedDict[bytes, str] = OrderedDict()
        self._routes: dict[str, Any] = {}

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if (
            scope["type"] != "http"
            or scope["method"] != "POST"
            or scope["path"] not in self.paths
            or scope.get("query_string")
        ):
            await self.app(scope, receive, send)
            return
        headers = dict(reversed(scope["headers"]))  # the first of repeated headers, as Starlette
        declared = headers.get(b"content-length")
        ctype = headers.get(b"content-type")
        accept = headers.get(b"accept")
        if (
            declared is None
            or not declared.isdigit()
            or int(declared) > FAST_BODY_MAX
            or not negotiation.json_declared(ctype.decode("latin-1") if ctype else None)
            or not negotiation.acceptable(accept.decode("latin-1") if accept else None, (JSON,))
        ):
            await self.app(scope, receive, send)
            return
        chunks: list[bytes] = []
        messages: list[Message] = []
        while True:
            message = await receive()
            messages.append(message)
            if message["type"] != "http.request":
                break  # a disconnect: the app sees it
            chunks.append(message.get("body", b""))
            if not message.get("more_body", False):
                break
        body = b"".join(chunks)
        digest = hashlib.sha256(scope["path"].encode() + b"\0" + body).digest()
        key = self._memo.get(digest)
        encoded = self.hits.get(key) if key is not None else None
        complete = messages[-1]["type"] == "http.request"  # not a disconnect
        if key is not None and encoded is not None and complete:
            self._memo.move_to_end(digest)
            scope["route"] = self._routes.get(scope["path"])  # for the route template
            coding = headers.get(b"accept-encoding")
            gzip_ok = accepts_gzip(coding.decode("latin-1") if coding else None)
            await result_response(key, True, encoded, gzip_ok)(scope, receive, send)
            return

        replay = iter(messages)

        async def replayed() -> Message:
            return next(replay, None) or await receive()

        async def learn(message: Message) -> None:
            if message["type"] == "http.response.start" and message["status"] == 200:
                location = MutableHeaders(scope=message).get("content-location", "")
                learned = _RESULT_LOCATION.fullmatch(location)
                if learned is not None:
                    self._memo[digest] = learned.group(1)
                    self._memo.move_to_end(digest)
                    if len(self._memo) > FAST_MEMO_SIZE:
                        self._memo.popitem(last=False)
            await send(message)

        await self.app(scope, replayed, learn)
        route = scope.get("route")
        if route is not None:
            self._routes[scope["path"]] = route  # the route that answered (metrics label)
