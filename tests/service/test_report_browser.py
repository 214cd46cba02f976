"""GET /v1/results/{key}/report.html and .pdf on a live server (issue 24): the HTML in
the real browser (every figure decoded and drawn, the key numbers shown), the PDF's pages
read back by pypdf.  Screenshots: ``report-html-v40``."""

from __future__ import annotations

import copy
import io
import re
from typing import Any

import httpx
import pytest

from pipeflow.schema.simulation import PAPER_EXAMPLE
from tests.service.browser import Page, open_page, page

#: slow (CI's second step): a real chromium and a server of its own: over 10 s a file
pytestmark = pytest.mark.slow

__all__ = ["page"]


def _diverged(server: str) -> dict[str, Any]:
    body = copy.deepcopy(PAPER_EXAMPLE)
    body["flow"] = {"velocity": {"kind": "constant", "value": 40.0}}
    body["time"] = {"t_end": 0.05, "samples": 501}
    body["modes"] = 6
    r = httpx.post(server + "/v1/simulations", json=body, timeout=120)
    assert r.status_code == 200, r.text
    result: dict[str, Any] = r.json()
    return result


def test_report_html_in_the_browser_and_pdf_pages(server: str, page: Page, screenshot: Any) -> None:
    result = _diverged(server)
    key = result["key"]
    assert result["status"] == "diverged"
    page.goto(f"{server}/v1/results/{key}/report.html")
    assert page.title() == "pipeflow report: simulation"
    page.wait_for_function(
        "[...document.images].length > 0 && [...document.images].every((i) => i.complete)"
    )
    widths = page.evaluate("[...document.images].map((i) => i.naturalWidth)")
    assert len(widths) == len(result["plots"][:6]) and all(w > 100 for w in widths)
    text = page.inner_text("body")
    assert "status\tdiverged" in text
    assert f"{result['divergence_growth_rate']:.6g}" in text
    assert "pipe.L\t0.025" in text  # the inputs, from the job record
    path = screenshot(page, "report-html-v40")
    assert path.stat().st_size > 10_000

    pypdf = pytest.importorskip("pypdf")
    r = httpx.get(f"{server}/v1/results/{key}/report.pdf", timeout=120)
    assert r.status_code == 200 and r.headers["content-type"] == "application/pdf"
    reader = pypdf.PdfReader(io.BytesIO(r.content))
    assert len(reader.pages) >= 1 + len(widths)
    flat = re.sub(r"\s+", " ", " ".join(p.extract_text() for p in reader.pages))
    assert "status diverged" in flat and f"key (parameter hash) {key}" in flat

    missing = httpx.get(f"{server}/v1/results/{'0' * 64}/report.pdf", timeout=30)
    assert missing.status_code == 404
    assert missing.headers["content-type"] == "application/problem+json"


def test_the_viewer_animates_the_mode_shapes(server: str, page: Page, screenshot: Any) -> None:
    """A result with mode shapes, opened in the viewer by its key: the animated GIF of
    the chosen branch is shown (decoded by the browser), and another branch redraws it."""
    body = copy.deepcopy(PAPER_EXAMPLE)
    body["flow"] = {"velocity": {"kind": "constant", "value": 10.0}}
    body["time"] = {"t_end": 0.01, "samples": 11}
    body["modes"] = 6
    body["output"] = {"mode_shapes": {"times": [0.0], "points": 31}}
    r = httpx.post(server + "/v1/simulations", json=body, timeout=120)
    assert r.status_code == 200, r.text
    key = r.json()["key"]
    open_page(page, f"{server}/?key={key}")
    page.locator("#mode-shapes").wait_for(state="visible")
    page.wait_for_function(
        "document.getElementById('shape-gif').complete"
        " && document.getElementById('shape-gif').naturalWidth > 100"
    )
    first = page.get_attribute("#shape-gif", "src")
    assert first is not None and "animations/mode_shapes.gif?mode=1" in first
    page.select_option("#shape-mode", "2")
    assert "mode=2" in (page.get_attribute("#shape-gif", "src") or "")
    gif = httpx.get(f"{server}/{first}", timeout=60)
    assert gif.status_code == 200 and gif.content.startswith(b"GIF8")
    page.locator("#mode-shapes").scroll_into_view_if_needed()
    screenshot(page, "viewer-mode-shape-animation")
    bad = httpx.get(f"{server}/v1/results/{key}/animations/mode_shapes.gif?mode=9", timeout=60)
    assert bad.status_code == 422 and bad.json()["errors"][0]["field"] == "mode"
