"""A deadline on receiving each request: its headers and body within ``read_timeout_s``.

uvicorn times out an idle keep-alive connection (``timeout_keep_alive``, after a
response) but waits without end for a request that is half sent: a client that opens a
connection and sends part of its headers, or a body shorter than its Content-Length,
holds the connection (and, for a body, the request's task) as long as it likes.  The HTTP
protocols here are uvicorn's own (httptools where installed, as uvicorn's ``auto``; or
h11) with one addition: from the connection's opening (its first request) or a request's
first byte, the whole request must arrive within the deadline
(:attr:`service.settings.Settings.read_timeout_s`, ``PIPEFLOW_READ_TIMEOUT_S``).  Past it
the server answers ``408 Request Timeout`` (a problem document, unless the app has started
its answer) and closes the connection; the app, if it was waiting for the body, sees the
client gone.  The time the app then takes to answer is not limited here.

uvicorn picks its protocol before it imports the app, so it is named on its command line:
``uvicorn service.main:app --http service.http.deadline:HTTPProtocol`` (the Dockerfile,
docker-compose and :func:`service.launch.serve` do; ``python -m service`` and
``pipeflow serve`` pass it themselves).
"""

from __future__ import annotations

import asyncio
import json
import logging
from typing import Any

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

from service.http.problems import PROBLEM_MEDIA_TYPE, problem

log = logging.getLogger("service")

__all__ = ["H11DeadlineProtocol", "HTTPProtocol", "deadline_protocol"]


def _timeout_answer(timeout_s: float) -> bytes:
    """The 408 sent when a request was not received in time (written to the socket: the
    app never saw the request, or is still waiting for its body)."""
    doc = problem(
        408,
        f"the request was not received within {timeout_s:g} s (its headers and body, from "
        "its first byte): send it again, whole",
        slug="request-timeout",
        title="Request timeout",
    )
    body = json.dumps(doc).encode()
    head = (
        "HTTP/1.1 408 Request Timeout\r\n"
        f"content-type: {PROBLEM_MEDIA_TYPE}\r\n"
        f"content-length: {len(body)}\r\n"
        "x-content-type-options: nosniff\r\n"
        "connection: close\r\n\r\n"
    )
    return head.encode("ascii") + body


class _Deadline:
    """The deadline of the request being received (mixed into a uvicorn protocol)."""

    #: the deadline [s]; None: the environment's settings (``PIPEFLOW_READ_TIMEOUT_S``)
    timeout_s: float | None = None
    _deadline: asyncio.TimerHandle | None = None
    # uvicorn's protocol attributes used here
    loop: asyncio.AbstractEventLoop
    transport: asyncio.Transport
    cycle: Any
    client: tuple[str, int] | None

    def _timeout(self) -> float:
        if self.timeout_s is None:
            from service.settings import get_settings

            type(self).timeout_s = get_settings().read_timeout_s
        assert self.timeout_s is not None
        return self.timeout_s

    def _arm(self) -> None:
        """Start the clock of a request (kept if it runs already)."""
        if self._deadline is None:
            self._deadline = self.loop.call_later(self._timeout(), self._expired)

    def _disarm(self) -> None:
        if self._deadline is not None:
            self._deadline.cancel()
            self._deadline = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        super().connection_made(transport)  # type: ignore[misc]
        self._arm()  # the first request, from the opening

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        super().connection_lost(exc)  # type: ignore[misc]

    def _headers_received(self) -> bool:
        raise NotImplementedError

    def _expired(self) -> None:
        self._deadline = None
        if self.transport.is_closing():
            return
        headers = self._headers_received()
        log.warning(
            "request not received within %g s (%s): connection closed",
            self._timeout(),
            "its body" if headers else "its headers",
            extra={"client": f"{self.client[0]}:{self.client[1]}" if self.client else None},
        )
        if not (headers and self.cycle is not None and self.cycle.response_started):
            self.transport.write(_timeout_answer(self._timeout()))
        self.transport.close()


class H11DeadlineProtocol(_Deadline, H11Protocol):
    """uvicorn's h11 protocol with the request deadline."""

    def handle_events(self) -> None:
        super().handle_events()
        state = self.conn.their_state
        if state is h11.SEND_BODY or (state is h11.IDLE and self.conn.trailing_data[0]):
            self._arm()  # a request under way (its body, or the start of its headers)
        elif state is not h11.IDLE:
            self._disarm()  # received (DONE), or the connection is ending

    def _headers_received(self) -> bool:
        return self.conn.their_state is not h11.IDLE


try:
    from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol
except ImportError:  # pragma: no cover - httptools is uvicorn[standard]'s
    HTTPProtocol: type[asyncio.Protocol] = H11DeadlineProtocol
else:

    class HttpToolsDeadlineProtocol(_Deadline, HttpToolsProtocol):
        """uvicorn's httptools protocol with the request deadline."""

        _headers_done = False

        def on_message_begin(self) -> None:
            super().on_message_begin()
            self._headers_done = False
            self._arm()

        def on_headers_complete(self) -> None:
            self._headers_done = True
            super().on_headers_complete()

        def on_message_complete(self) -> None:
            super().on_message_complete()
            self._disarm()

        def _headers_received(self) -> bool:
            return self._headers_done

    HTTPProtocol = HttpToolsDeadlineProtocol


def deadline_protocol(timeout_s: float) -> type[asyncio.Protocol]:
    """:data:`HTTPProtocol` with a deadline of ``timeout_s`` [s] (``uvicorn.run(...,
    http=deadline_protocol(settings.read_timeout_s))``)."""
    return type(HTTPProtocol.__name__, (HTTPProtocol,), {"timeout_s": timeout_s})
