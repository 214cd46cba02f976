"""Security headers on every answer, 5xx bodies without internal text, and malformed
bodies (invalid UTF-8, broken JSON) answered 400 with the byte offset.

The app runs without its lifespan (no store, no workers): every answer checked here is
given before a route would touch the engine (pages, documentation, 404s, 405s, 413s, the
body parser's 400s) or by a route of this module.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi import APIRouter
from fastapi.testclient import TestClient

from pipeflow.errors import ErrorRecord, StorageError
from service.http.problems import record_problem, storage_problem, stored_problem
from service.http.security import API_CSP, DOCS_CSP, PAGE_CSP, SVG_CSP
from service.main import create_app
from service.settings import Settings
from tests.service.conftest import SMALL

SECRET = "secret-internal-text-3f9a"


def _crashing_router() -> APIRouter:
    router = APIRouter()

    @router.get("/test/crash")
    async def crash() -> None:
        raise RuntimeError(SECRET)

    return router


@pytest.fixture(scope="module")
def tc(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    app = create_app(Settings(data_dir=tmp_path_factory.mktemp("hardening"), max_body_bytes=4096))
    app.include_router(_crashing_router())
    yield TestClient(app, raise_server_exceptions=False)  # no lifespan: no workers needed


def _directives(csp: str) -> dict[str, str]:
    return {d.split()[0]: d.partition(" ")[2] for d in (p.strip() for p in csp.split(";")) if d}


def _assert_secured(headers: object, what: str) -> dict[str, str]:
    h = dict(headers)  # type: ignore[call-overload]
    assert h.get("x-content-type-options") == "nosniff", what
    assert h.get("x-frame-options") == "DENY", what
    csp = _directives(h.get("content-security-policy", ""))
    assert csp.get("frame-ancestors") == "'none'", (what, csp)
    assert csp.get("object-src") == "'none'" and csp.get("base-uri") == "'none'", (what, csp)
    return csp


PAGES = ("/", "/stability", "/frequency-response", "/studies")


@pytest.mark.parametrize("path", PAGES)
def test_pages_allow_this_origin_only_and_no_inline_code(tc: TestClient, path: str) -> None:
    r = tc.get(path)
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    csp = _assert_secured(r.headers, path)
    assert r.headers["content-security-policy"] == PAGE_CSP
    for directive in ("default-src", "script-src", "style-src", "connect-src"):
        assert csp[directive] == "'self'", (directive, csp)
    # the policy holds because the pages have no inline script, style or handler (the
    # browser tests load every page under it and fail on any console error)
    assert "<script>" not in r.text and "<style" not in r.text and " style=" not in r.text
    assert " onclick=" not in r.text and " onload=" not in r.text


@pytest.mark.parametrize("path", ["/docs", "/redoc"])
def test_documentation_pages_keep_their_inline_configuration(tc: TestClient, path: str) -> None:
    r = tc.get(path)
    assert r.status_code == 200
    csp = _assert_secured(r.headers, path)
    assert r.headers["content-security-policy"] == DOCS_CSP
    assert csp["default-src"] == "'self'" and "'unsafe-inline'" in csp["script-src"]


def test_every_other_answer_is_secured_and_loads_nothing(tc: TestClient) -> None:
    answers = {
        "asset": tc.get("/static/viewer.js"),
        "document asset": tc.get("/static/docs/favicon.png"),
        "openapi": tc.get("/openapi.json"),
        "health": tc.get("/healthz"),
        "404 problem": tc.get("/v1/nowhere"),
        "405 problem": tc.delete("/v1/simulations"),
        "415 problem": tc.post("/v1/simulations", content=b"x", headers={"Content-Type": "text/x"}),
        "413 of the body limit": tc.post("/v1/simulations", content=b"[" + b" " * 5000 + b"]"),
        "422 problem": tc.get("/v1/results/not-a-key"),
        "500 problem": tc.get("/test/crash"),
    }
    for what, r in answers.items():
        _assert_secured(r.headers, what)
        assert r.headers["content-security-policy"] == API_CSP, what
        assert _directives(API_CSP)["default-src"] == "'none'"
    assert answers["413 of the body limit"].status_code == 413
    assert answers["500 problem"].status_code == 500


def test_svg_policy_allows_inline_styles_and_nothing_else() -> None:
    """The SVG figure route's own policy (checked on a real figure in test_results_export)."""
    csp = _directives(SVG_CSP)
    assert csp["default-src"] == "'none'" and csp["style-src"] == "'unsafe-inline'"
    assert "script-src" not in csp  # falls back to default-src 'none': no script runs


def test_unhandled_error_answers_the_request_id_not_the_text(
    tc: TestClient, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.ERROR):
        r = tc.get("/test/crash", headers={"X-Request-ID": "crash-probe-1"})
    assert r.status_code == 500
    assert r.headers["content-type"] == "application/problem+json"
    assert SECRET not in r.text and "RuntimeError" not in r.text
    doc = r.json()
    assert doc["request_id"] == "crash-probe-1" == r.headers["x-request-id"]
    assert "crash-probe-1" in doc["detail"] and doc["type"].endswith("/internal")
    # the text and its traceback are in the log, under the request id
    logged = [rec for rec in caplog.records if rec.exc_info and SECRET in str(rec.exc_info[1])]
    assert logged and getattr(logged[0], "request_id", None) == "crash-probe-1"


def test_engine_records_of_5xx_carry_no_internal_text(caplog: pytest.LogCaptureFixture) -> None:
    """An internal error of a computation (the worker's exception text, e.g. defect 2's
    'IndexError: index 0 is out of bounds') and a store's driver text stay in the log."""
    internal = ErrorRecord.internal(f"internal error: IndexError: {SECRET}")
    with caplog.at_level(logging.WARNING):
        for doc in (record_problem(internal), stored_problem(internal.to_dict())):
            assert doc["status"] == 500 and SECRET not in json.dumps(doc), doc
            assert "request_id" in doc
        storage = ErrorRecord(
            "storage", "storage", f"disk I/O error ({SECRET})", data={"full": True}
        )
        doc = record_problem(storage)
        assert doc["status"] == 507 and SECRET not in json.dumps(doc)
        assert "could not be stored" in doc["detail"] and "full" in doc["detail"]
        for full in (False, True):
            doc = storage_problem(StorageError(f"the store failed ({SECRET})", full=full))
            assert doc["status"] == (507 if full else 503) and SECRET not in json.dumps(doc)
    assert sum(SECRET in rec.getMessage() for rec in caplog.records) == 3  # 2 internal, 1 storage
    # a refusal (4xx) keeps its message: it is about the client's input
    refused = ErrorRecord("refused", "budget-exceeded", "modes: at most 40", field="modes")
    assert record_problem(refused)["detail"] == "modes: at most 40"


# -- malformed bodies (defect 7) -------------------------------------------------------------


@pytest.mark.parametrize("content_type", ["application/json", None])
def test_invalid_utf8_body_names_the_body_and_the_byte_offset(
    tc: TestClient, content_type: str | None
) -> None:
    body = json.dumps(SMALL).encode()
    cut = body.index(b'"modes"') + 2
    bad = body[:cut] + b"\xff\xfe" + body[cut:]
    headers = {"Content-Type": content_type} if content_type else {}
    r = tc.post("/v1/simulations", content=bad, headers=headers)
    assert r.status_code == 400, r.text
    assert r.headers["content-type"] == "application/problem+json"
    doc = r.json()
    assert doc["type"].endswith("/malformed-json")
    [err] = doc["errors"]
    assert err["location"] == "body" and err["field"] is None and err["pointer"] == "#"
    assert err["type"] == "utf8_invalid" and err["offset"] == cut
    assert f"byte offset {cut}" in err["message"]
    # the offset is where decoding fails: the bytes before it are valid UTF-8
    bad[: err["offset"]].decode("utf-8")
    with pytest.raises(UnicodeDecodeError):
        bad[err["offset"] : err["offset"] + 1].decode("utf-8")


def test_invalid_utf8_also_on_the_hit_fast_path(tc: TestClient) -> None:
    """A small JSON body is read by the hit fast path first; a miss goes on to the route,
    which answers the same 400 (the fast path never parses)."""
    bad = b'{"modes": "\xc3"}'
    r = tc.post("/v1/stability", content=bad, headers={"Content-Type": "application/json"})
    assert r.status_code == 400 and r.json()["errors"][0]["offset"] == bad.index(b"\xc3")


def test_broken_json_names_the_byte_offset_not_the_character(tc: TestClient) -> None:
    """JSON's own errors carry a character position; the problem gives the byte offset
    (they differ once a multi-byte character precedes the error)."""
    body = '{"tag": "\u00e9\u00e9\u00e9", "modes": 3,}'.encode()  # a trailing comma
    r = tc.post("/v1/simulations", content=body, headers={"Content-Type": "application/json"})
    assert r.status_code == 400
    [err] = r.json()["errors"]
    assert err["type"] == "json_invalid" and err["offset"] == body.rindex(b"}")
    assert err["offset"] != body.decode().rindex("}")  # 3 two-byte characters before it
    assert f"byte offset {err['offset']}" in err["message"]


def test_defaults_keep_the_committed_openapi(tmp_path: Path) -> None:
    """The security schemes appear in the document only when keys are required."""
    doc = create_app(Settings(data_dir=tmp_path)).openapi()
    assert "securitySchemes" not in doc.get("components", {})
