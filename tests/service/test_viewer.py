"""The viewer page at / and its vendored assets (served without a browser)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from html.parser import HTMLParser
from typing import Any

import pytest

from pipeflow.schema.simulation import PAPER_EXAMPLE
from service.routes.viewer import ASSETS
from tests.service.conftest import make_client


class _Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.options: list[str] = []
        self.scripts: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "option":
            self.options.append(str(a.get("value")))
        elif tag == "script" and a.get("src"):
            self.scripts.append(str(a["src"]))


@pytest.fixture(scope="module")
def tc(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    with make_client(tmp_path_factory.mktemp("viewer")) as c:
        yield c


@pytest.mark.parametrize(
    ("path", "scripts"),
    [
        (
            "/",
            [
                "static/uPlot.iife.min.js",
                "static/schemaform.js",
                "static/pages.js",
                "static/viewer.js",
            ],
        ),
        ("/stability", ["static/schemaform.js", "static/pages.js", "static/stability.js"]),
        (
            "/frequency-response",
            [
                "static/uPlot.iife.min.js",
                "static/schemaform.js",
                "static/pages.js",
                "static/frequency.js",
            ],
        ),
        (
            "/studies",
            [
                "static/uPlot.iife.min.js",
                "static/schemaform.js",
                "static/pages.js",
                "static/studies.js",
            ],
        ),
    ],
)
def test_pages_build_their_forms_from_the_schema(tc: Any, path: str, scripts: list[str]) -> None:
    """Both pages are shells whose forms schemaform.js generates from /openapi.json: no
    method, profile kind or analysis is written into the HTML (the only options are the
    tip chart's scale choice), and every script is vendored (nothing from another origin)."""
    r = tc.get(path)
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    page = _Page()
    page.feed(r.text)
    assert page.scripts == scripts
    assert set(page.options) <= {"auto", "linear", "symlog"}
    assert not re.search(r"(src|href)=\"(https?:)?//", r.text)


def test_the_schema_carries_what_the_forms_read(tc: Any) -> None:
    """The forms read the request schemas from the operations' request bodies, prefill the
    simulation form with the schema's example (the paper's case, PAPER_EXAMPLE) and the
    stability analyses with theirs; the method comes from the schema's default."""
    doc = tc.get("/openapi.json").json()

    def body(path: str) -> dict[str, Any]:
        content: dict[str, Any] = doc["paths"][path]["post"]["requestBody"]["content"]
        return content["application/json"]

    ref = body("/v1/simulations")["schema"]["$ref"].split("/")[-1]
    sim = doc["components"]["schemas"][ref]
    assert sim["examples"][0] == PAPER_EXAMPLE
    assert sim["properties"]["method"]["default"] in sim["properties"]["method"]["enum"]
    assert doc["components"]["schemas"][body("/v1/stability")["schema"]["$ref"].split("/")[-1]][
        "examples"
    ]
    sweeps = body("/v1/sweeps")
    kinds = set(sweeps["schema"]["discriminator"]["mapping"])
    assert kinds == set(sweeps["examples"])


@pytest.mark.parametrize("name", sorted(ASSETS))
def test_assets_are_served(tc: Any, name: str) -> None:
    r = tc.get(f"/static/{name}")
    assert r.status_code == 200
    assert r.headers["content-type"] == ASSETS[name]
    assert len(r.content) > 100


def test_only_listed_assets_are_served(tc: Any) -> None:
    for path in ("/static/index.html.bak", "/static/..%2F..%2Fmain.py", "/static/.env"):
        r = tc.get(path)
        assert r.status_code == 404
    assert tc.get("/static/%2E%2E/routes/viewer.py").status_code == 404


def test_viewer_is_not_part_of_the_api_document(tc: Any) -> None:
    paths = tc.get("/openapi.json").json()["paths"]
    assert "/" not in paths and not any(p.startswith("/static") for p in paths)
