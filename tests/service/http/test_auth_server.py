"""Authentication and malformed HTTP against a real uvicorn with its Dask workers.

One server requires keys (``PIPEFLOW_AUTH_REQUIRED=true``, one key in the environment, one
in a keys file, /metrics for the scraper's key only).  Checked: the API, the job routes
and the cache-hit fast path need a key; the probes do not; /metrics answers 401/403/200;
each request's log line names its key id and no key is ever written to the log.  And
uvicorn's own answers to broken HTTP framing: a text/plain 400 that never reaches the app
(README, "Errors").
"""

from __future__ import annotations

import json
import socket
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import httpx
import pytest

from service.http.auth import new_key
from tests.service.conftest import SMALL
from tests.service.processes import server

#: slow: a real server with a worker starts in 10-25 s here
pytestmark = pytest.mark.slow

ALICE, ALICE_ENTRY = new_key("alice")
SCRAPER, SCRAPER_ENTRY = new_key("prometheus")


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, Path]]:
    tmp = tmp_path_factory.mktemp("auth-server")
    keys = tmp / "keys"
    keys.write_text(f"{SCRAPER_ENTRY}\n")
    log = tmp / "server.log"
    with server(
        log,
        ready=True,
        PIPEFLOW_DATA_DIR=str(tmp),
        PIPEFLOW_WORKERS="1",
        PIPEFLOW_AUTH_REQUIRED="true",
        PIPEFLOW_API_KEYS=ALICE_ENTRY,
        PIPEFLOW_API_KEYS_FILE=str(keys),
        PIPEFLOW_METRICS_KEY_IDS="prometheus",
    ) as (_, url):
        yield url, log


def _log_lines(log: Path) -> list[dict[str, Any]]:
    out = []
    for line in log.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except ValueError:
            continue
    return out


def test_the_api_needs_a_key_and_the_fast_path_too(live: tuple[str, Path]) -> None:
    url, log = live
    alice = {"Authorization": f"Bearer {ALICE}"}
    first = httpx.post(f"{url}/v1/simulations", json=SMALL, headers=alice, timeout=60)
    assert first.status_code == 200 and first.headers["x-cache"] == "MISS", first.text
    hit = httpx.post(f"{url}/v1/simulations", json=SMALL, headers=alice, timeout=60)
    assert hit.status_code == 200 and hit.headers["x-cache"] == "HIT"
    # the same bytes without a key, or with another: refused, not answered from the cache
    for headers in ({}, {"Authorization": f"Bearer {SCRAPER[:-1]}x"}, {"X-API-Key": "pf_"}):
        r = httpx.post(f"{url}/v1/simulations", json=SMALL, headers=headers, timeout=60)
        assert r.status_code == 401 and "x-cache" not in r.headers, r.text
        assert r.headers["content-type"] == "application/problem+json"
        assert r.headers["www-authenticate"].startswith("Bearer")
    key = first.json()["key"]
    assert httpx.get(f"{url}/v1/results/{key}").status_code == 401
    assert httpx.get(f"{url}/v1/results/{key}", headers={"X-API-Key": ALICE}).status_code == 200

    job = {**SMALL, "initial": {"u0": 0.002}}
    assert httpx.post(f"{url}/v1/jobs", json=job).status_code == 401
    accepted = httpx.post(f"{url}/v1/jobs", json=job, headers={"X-API-Key": SCRAPER})
    assert accepted.status_code == 202, accepted.text
    assert httpx.get(f"{url}{accepted.headers['location']}").status_code == 401

    lines = [rec for rec in _log_lines(log) if rec.get("message") == "request"]
    mine = [rec for rec in lines if rec.get("path") == "/v1/simulations"]
    assert [rec["principal"] for rec in mine[:2]] == ["alice", "alice"]
    assert [rec["status"] for rec in mine[2:5]] == [401, 401, 401]
    assert all(rec["principal"] is None for rec in mine[2:5])
    jobs = [rec for rec in lines if rec.get("path") == "/v1/jobs" and rec["status"] == 202]
    assert jobs and jobs[0]["principal"] == "prometheus"
    text = log.read_text()
    assert ALICE not in text and SCRAPER not in text  # keys are never logged


def test_the_job_of_a_key_can_be_followed_with_it(live: tuple[str, Path]) -> None:
    url, _ = live
    job = {**SMALL, "initial": {"u0": 0.003}}
    headers = {"X-API-Key": ALICE}
    accepted = httpx.post(f"{url}/v1/jobs", json=job, headers=headers)
    assert accepted.status_code == 202
    end = wait_job_with(url, accepted.json()["key"], headers)
    assert end["status"] == "succeeded", end


def wait_job_with(url: str, key: str, headers: dict[str, str]) -> dict[str, Any]:
    """:func:`tests.service.processes.wait_job` with a key (it polls without one)."""
    deadline = time.monotonic() + 120
    while True:
        r = httpx.get(f"{url}/v1/jobs/{key}", headers=headers, timeout=10)
        assert r.status_code == 200, r.text
        if r.json()["status"] in ("succeeded", "failed", "cancelled"):
            return dict(r.json())
        assert time.monotonic() < deadline
        time.sleep(0.1)


def test_probes_stay_open_and_metrics_have_their_own_keys(live: tuple[str, Path]) -> None:
    url, _ = live
    assert httpx.get(f"{url}/healthz").status_code == 200
    assert httpx.get(f"{url}/readyz").status_code == 200
    assert httpx.get(f"{url}/metrics").status_code == 401
    forbidden = httpx.get(f"{url}/metrics", headers={"X-API-Key": ALICE})
    assert forbidden.status_code == 403
    assert forbidden.headers["content-type"] == "application/problem+json"
    scraped = httpx.get(f"{url}/metrics", headers={"Authorization": f"Bearer {SCRAPER}"})
    assert scraped.status_code == 200 and "pipeflow_http_requests_total" in scraped.text


def _raw(url: str, request: bytes) -> bytes:
    parts = urlsplit(url)
    with socket.create_connection((parts.hostname, parts.port), timeout=10) as sock:
        sock.sendall(request)
        chunks = []
        while chunk := sock.recv(65536):
            chunks.append(chunk)
    return b"".join(chunks)


@pytest.mark.parametrize(
    ("request_bytes", "headers_valid"),
    [
        (b"POST /v1/simulations HTTP/1.1\r\nHost: x\r\nContent-Length: abc\r\n\r\n{}", False),
        (b"GET /healthz HTTP/1.1\r\nHost: x\r\nBad Header Line\r\n\r\n", False),
        (
            b"POST /v1/simulations HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n",
            True,
        ),
    ],
    ids=["content-length", "header-line", "chunk-size"],
)
def test_broken_framing_gets_uvicorns_text_400(
    live: tuple[str, Path], request_bytes: bytes, headers_valid: bool
) -> None:
    """uvicorn's HTTP parser refuses these itself: a text/plain 400 without a request id,
    a problem document or the security headers, and closes the connection (the README
    says so).  Broken headers never reach the app (no log line of it); a broken body after
    valid headers may start the app, whose answer is then never sent."""
    url, log = live
    before = len([r for r in _log_lines(log) if r.get("message") == "request"])
    answer = _raw(url, request_bytes)
    head, _, body = answer.partition(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    assert lines[0] == "HTTP/1.1 400 Bad Request", answer
    headers = {k.lower(): v.strip() for k, _, v in (h.partition(":") for h in lines[1:])}
    assert headers["content-type"] == "text/plain; charset=utf-8"
    assert headers["connection"] == "close"
    assert "x-request-id" not in headers and "content-security-policy" not in headers
    assert body == b"Invalid HTTP request received."
    if not headers_valid:
        after = len([r for r in _log_lines(log) if r.get("message") == "request"])
        assert after == before
