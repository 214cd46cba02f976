"""The request deadline (service.http.deadline, issue 34 item 4) in a real uvicorn server on a
real socket, for both of uvicorn's HTTP parsers: a request whose headers and body have not
arrived within the deadline is answered 408 and its connection closed; a complete request
is never cut, however long the app takes or however long the connection idled before it.

The app is a small ASGI echo (the body's length), so that each case runs in a fraction
of a second; tests/service/http/test_request_guards_server.py checks the service itself.
"""

from __future__ import annotations

import asyncio
import json
import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest
import uvicorn

from service.http.deadline import H11DeadlineProtocol, HTTPProtocol, deadline_protocol
from service.launch import free_port

#: the deadline of these servers [s]
DEADLINE = 0.5
#: generous bound on the close after the deadline [s] (a loaded machine)
SLACK = 2.0

PROTOCOLS = {"auto": HTTPProtocol, "h11": H11DeadlineProtocol}


async def echo(scope: dict[str, Any], receive: Any, send: Any) -> None:
    """The body's length; ``/slow`` first waits 3 deadlines; records disconnects."""
    size, more = 0, True
    while more:
        message = await receive()
        if message["type"] == "http.disconnect":
            DISCONNECTS.append(scope["path"])
            return
        size += len(message.get("body", b""))
        more = message.get("more_body", False)
    if scope["path"] == "/slow":
        await asyncio.sleep(3 * DEADLINE)
    body = str(size).encode()
    headers = [(b"content-type", b"text/plain"), (b"content-length", str(len(body)).encode())]
    await send({"type": "http.response.start", "status": 200, "headers": headers})
    await send({"type": "http.response.body", "body": body})


DISCONNECTS: list[str] = []


@contextmanager
def running(protocol: type[asyncio.Protocol]) -> Iterator[int]:
    port = free_port()
    config = uvicorn.Config(
        echo,
        host="127.0.0.1",
        port=port,
        http=protocol,
        lifespan="off",
        log_level="warning",
        timeout_keep_alive=5,
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    end = time.monotonic() + 10
    while not server.started:
        assert time.monotonic() < end, "the server did not start"
        time.sleep(0.01)
    try:
        yield port
    finally:
        server.should_exit = True
        thread.join(10)


@pytest.fixture(params=list(PROTOCOLS), scope="module")
def port(request: pytest.FixtureRequest) -> Iterator[int]:
    with running(deadline_protocol(DEADLINE) if request.param == "auto" else _h11()) as p:
        yield p


def _h11() -> type[asyncio.Protocol]:
    return type("H11", (H11DeadlineProtocol,), {"timeout_s": DEADLINE})


def _read_until_closed(sock: socket.socket, limit_s: float) -> tuple[bytes, float]:
    """Everything the server sends until it closes, and when it closed [s from now]."""
    start = time.monotonic()
    sock.settimeout(limit_s)
    chunks = []
    while True:
        try:
            data = sock.recv(65536)
        except TimeoutError:
            pytest.fail(f"the connection was still open after {limit_s} s")
        if not data:
            return b"".join(chunks), time.monotonic() - start
        chunks.append(data)


def _assert_408(answer: bytes) -> None:
    head, _, body = answer.partition(b"\r\n\r\n")
    assert head.startswith(b"HTTP/1.1 408 "), answer
    assert b"content-type: application/problem+json" in head.lower()
    doc = json.loads(body)
    assert doc["status"] == 408 and doc["type"].endswith("/request-timeout")
    assert f"within {DEADLINE:g} s" in doc["detail"]


def test_headers_trickling_past_the_deadline_are_cut(port: int) -> None:
    """A byte of the headers every 0.1 s (a slowloris client): the deadline counts from
    the first byte, not between bytes."""
    with socket.create_connection(("127.0.0.1", port)) as sock:
        request = b"POST /echo HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
        start = time.monotonic()
        try:
            for byte in request:
                sock.sendall(bytes([byte]))
                time.sleep(0.1)
        except OSError:
            pass  # closed while trickling: the point
        answer, _ = _read_until_closed(sock, DEADLINE + SLACK)
        assert time.monotonic() - start < DEADLINE + SLACK
    _assert_408(answer)


def test_a_body_short_of_its_length_is_cut_and_the_app_sees_the_client_go(port: int) -> None:
    DISCONNECTS.clear()
    with socket.create_connection(("127.0.0.1", port)) as sock:
        sock.sendall(b"POST /short HTTP/1.1\r\nHost: x\r\nContent-Length: 100\r\n\r\n0123456789")
        answer, _ = _read_until_closed(sock, DEADLINE + SLACK)
    _assert_408(answer)
    end = time.monotonic() + SLACK
    while DISCONNECTS != ["/short"]:
        assert time.monotonic() < end, DISCONNECTS
        time.sleep(0.01)


def test_a_connection_that_sends_nothing_is_closed(port: int) -> None:
    with socket.create_connection(("127.0.0.1", port)) as sock:
        answer, _ = _read_until_closed(sock, DEADLINE + SLACK)
    _assert_408(answer)


def test_complete_requests_are_not_cut_however_long_the_app_or_the_idle(port: int) -> None:
    """An app answering after 3 deadlines is waited for; a second request on the same
    connection after an idle longer than the deadline (shorter than keep-alive's 5 s) is
    answered: the clock starts at a request's first byte."""
    with socket.create_connection(("127.0.0.1", port)) as sock:
        sock.settimeout(10)
        sock.sendall(b"POST /slow HTTP/1.1\r\nHost: x\r\nContent-Length: 3\r\n\r\nabc")
        assert sock.recv(65536).startswith(b"HTTP/1.1 200 ")
        time.sleep(2 * DEADLINE)
        sock.sendall(b"POST /echo HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\n\r\nab")
        answer = sock.recv(65536)
        assert answer.startswith(b"HTTP/1.1 200 ") and answer.endswith(b"\r\n\r\n2")
