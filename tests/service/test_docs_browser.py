"""/docs (Swagger UI) and /redoc work offline: headless chromium with every request that
leaves 127.0.0.1 aborted loads both pages and sees every operation of the API.

The assets come from the fastapi-offline package (served under ``/static/docs/``);
before, Swagger UI loaded from a CDN and the page stayed blank without internet.  A
screenshot of each page goes to the run's temporary directory; pytest's summary lists them.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any
from urllib.parse import urlsplit

import pytest

from tests.live import ROOT

#: slow (CI's second step): a real chromium and a server of its own: over 10 s a file
pytestmark = pytest.mark.slow

#: every operationId of the committed OpenAPI document (the pages must show them all)
OPERATIONS = sorted(
    op["operationId"]
    for item in json.loads((ROOT / "openapi" / "openapi.json").read_text())["paths"].values()
    for op in item.values()
)


@pytest.fixture
def offline_page(browser: Any) -> Iterator[tuple[Any, list[str]]]:
    """A page whose requests to any host but 127.0.0.1 are aborted; yields it and the list
    of the URLs it tried to reach outside."""
    context = browser.new_context(viewport={"width": 1200, "height": 900})
    blocked: list[str] = []

    def route(r: Any) -> None:
        url = r.request.url
        host = urlsplit(url).hostname
        if url.startswith(("data:", "blob:")) or host == "127.0.0.1":
            r.continue_()
        else:
            blocked.append(url)
            r.abort()

    context.route("**/*", route)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.set_default_timeout(60_000)
    yield page, blocked
    context.close()
    assert not errors, errors


def test_swagger_ui_shows_every_operation_offline(
    server: str, offline_page: tuple[Any, list[str]], screenshot: Any
) -> None:
    page, blocked = offline_page
    page.goto(server + "/docs")
    page.wait_for_selector(".opblock")
    # Swagger UI gives each operation block the id "operations-<tag>-<operationId>"
    ids = page.eval_on_selector_all(".opblock", "els => els.map(e => e.id)")
    shown = sorted(i.rpartition("-")[2] for i in ids)
    assert shown == OPERATIONS
    assert "pipeflow" in page.inner_text(".info .title")
    assert screenshot(page, "docs").stat().st_size > 10_000  # a rendered page, not a blank one
    assert blocked == []


def test_redoc_shows_every_operation_offline(
    server: str, offline_page: tuple[Any, list[str]], screenshot: Any
) -> None:
    page, blocked = offline_page
    page.goto(server + "/redoc")
    page.wait_for_selector("[data-section-id^='operation/']")
    sections = page.eval_on_selector_all(
        "[data-section-id^='operation/']", "els => els.map(e => e.dataset.sectionId)"
    )
    assert sorted({s.removeprefix("operation/") for s in sections}) == OPERATIONS
    assert screenshot(page, "redoc").stat().st_size > 10_000
    assert blocked == []


def test_the_viewer_links_to_the_offline_docs(
    server: str, offline_page: tuple[Any, list[str]]
) -> None:
    page, _ = offline_page
    page.goto(server + "/")
    page.click("text=API documentation")
    page.wait_for_selector(".opblock")
    assert urlsplit(page.url).path == "/docs"
