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


class _Inputs(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.values: dict[str, str] = {}
        self.select: str | None = None
        self.scripts: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "input" and a.get("name"):
            self.values[str(a["name"])] = str(a.get("value", ""))
        elif tag == "select":
            self.select = a.get("name")
        elif tag == "option" and self.select and "selected" in a:
            self.values[self.select] = str(a.get("value"))
        elif tag == "script" and a.get("src"):
            self.scripts.append(str(a["src"]))


@pytest.fixture(scope="module")
def tc(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    with make_client(tmp_path_factory.mktemp("viewer")) as c:
        yield c


def test_page_is_prefilled_with_the_papers_example(tc: Any) -> None:
    r = tc.get("/")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    form = _Inputs()
    form.feed(r.text)
    v = form.values
    ex = PAPER_EXAMPLE
    for k, value in ex["pipe"].items():
        assert float(v[f"pipe.{k}"]) == value, k
    assert v["rotation.omega0.kind"] == ex["rotation"]["omega0"]["kind"]
    assert float(v["rotation.omega0.value"]) == ex["rotation"]["omega0"]["value"]
    assert v["flow.velocity.kind"] == ex["flow"]["velocity"]["kind"]
    coefficients = [float(c) for c in v["flow.velocity.coefficients"].split(",")]
    assert coefficients == ex["flow"]["velocity"]["coefficients"]
    assert float(v["initial.u0"]) == ex["initial"]["u0"]
    assert float(v["initial.du0"]) == ex["initial"]["du0"]
    assert int(v["modes"]) == ex["modes"]
    assert float(v["time.t_end"]) == ex["time"]["t_end"]
    assert int(v["time.samples"]) == ex["time"]["samples"]
    assert v["method"] == ex["method"]
    # every script is vendored: nothing is fetched from another origin
    assert form.scripts == ["static/uPlot.iife.min.js", "static/viewer.js"]
    assert not re.search(r"(src|href)=\"(https?:)?//", r.text)


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
