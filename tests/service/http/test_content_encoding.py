"""Request bodies by their Content-Encoding (issue 34, item 4): gzip is inflated (within the
body limit), identity is the body as it is, any other coding is a 415 problem naming the
header, with ``Accept-Encoding: gzip, identity`` (RFC 9110 section 15.5.16).  The real app:
its Dask worker and store."""

from __future__ import annotations

import gzip
import json
from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient

from tests.service.conftest import SMALL, make_client, wait_ready

#: the body limit of this module's app [bytes]
LIMIT = 64 * 1024
BODY = json.dumps({**SMALL, "initial": {"u0": 0.0031}}).encode()


@pytest.fixture(scope="module")
def app(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with make_client(
        tmp_path_factory.mktemp("content-encoding"), workers=1, max_body_bytes=LIMIT
    ) as c:
        wait_ready(c)
        yield c


def _post(
    app: TestClient, body: bytes, coding: str | None, path: str = "/v1/jobs"
) -> httpx.Response:
    headers = {"content-type": "application/json"}
    if coding is not None:
        headers["content-encoding"] = coding
    return app.post(path, content=body, headers=headers)


def test_a_gzip_body_is_the_same_request(app: TestClient) -> None:
    plain = app.post("/v1/jobs", content=BODY, headers={"content-type": "application/json"})
    assert plain.status_code == 202, plain.text
    for coding in ("gzip", "x-gzip", "GZIP", "identity, gzip"):
        packed = _post(app, gzip.compress(BODY), coding)
        assert packed.status_code == 202, (coding, packed.text)
        assert packed.json()["key"] == plain.json()["key"]
    # two gzip members one after the other are one body (RFC 1952)
    half = len(BODY) // 2
    members = gzip.compress(BODY[:half]) + gzip.compress(BODY[half:])
    assert _post(app, members, "gzip").json()["key"] == plain.json()["key"]
    assert _post(app, BODY, "identity").json()["key"] == plain.json()["key"]


@pytest.mark.parametrize("coding", ["br", "deflate", "compress", "zstd", "gzip, gzip", "gzip, br"])
def test_another_coding_is_a_415_naming_the_header(app: TestClient, coding: str) -> None:
    resp = _post(app, gzip.compress(BODY), coding)
    assert resp.status_code == 415
    assert resp.headers["content-type"] == "application/problem+json"
    assert resp.headers["accept-encoding"] == "gzip, identity"
    doc = resp.json()
    assert doc["type"].endswith("/unsupported-content-encoding")
    assert [(e["field"], e["location"]) for e in doc["errors"]] == [("Content-Encoding", "header")]
    assert repr(coding) in doc["detail"]


def test_a_415_comes_before_the_hit_fast_path(app: TestClient) -> None:
    """The exact bytes of an answered request, now declared brotli, are refused: the fast
    path never answers a body the server cannot read."""
    body = json.dumps({**SMALL, "initial": {"u0": 0.0032}}).encode()
    first = app.post("/v1/simulations", content=body, headers={"content-type": "application/json"})
    assert first.status_code == 200, first.text
    assert _post(app, body, None, "/v1/simulations").headers["x-cache"] == "HIT"
    assert _post(app, body, "br", "/v1/simulations").status_code == 415


def test_broken_or_oversized_gzip_is_a_4xx_problem(app: TestClient) -> None:
    def problem(body: bytes, status: int) -> dict[str, Any]:
        resp = _post(app, body, "gzip")
        assert resp.status_code == status, resp.text
        assert resp.headers["content-type"] == "application/problem+json"
        return resp.json()

    assert "not valid gzip" in str(problem(BODY, 400)["detail"])  # not compressed at all
    assert "ends early" in str(problem(gzip.compress(BODY)[:-12], 400)["detail"])
    # a small body that inflates past the limit: inflating stops there
    bomb = gzip.compress(b" " * (LIMIT + 1), 9)
    assert len(bomb) < 1024
    assert f"limit of {LIMIT} bytes" in str(problem(bomb, 413)["detail"])
    # 64 MB of spaces in ~64 kB: the first LIMIT bytes of it inflate ~1000-fold
    big = gzip.compress(b" " * (64 << 20), 9)
    assert f"limit of {LIMIT} bytes" in str(problem(big[:LIMIT], 413)["detail"])
    # gzip of something that is not JSON: the JSON error, with its byte offset
    doc = problem(gzip.compress(b'{"pipe": '), 400)
    assert doc["type"] == "https://pipeflow.dev/problems/malformed-json"
