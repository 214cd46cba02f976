"""Units and reports in the pages, in a real headless browser (issue 24; set-up and
screenshots: ``tests/conftest.py``, ``tests/service/browser.py``).

Checks: the viewer's form offers a unit beside the fields the API takes as quantities (rpm
or Hz for a spin, mm for a length) and sends ``{"value", "unit"}`` for a unit that is not
SI; 3000 rpm typed in the form is the result of 100 pi rad/s (one cache key: the second
run is answered from the cache) and 25 mm that of 0.025 m; a shared link keeps the unit;
the frequency chart's axis in Hz plots omega / 2 pi; the result links its report (HTML
and PDF), on the viewer and on the stability page, whose figures' spin and frequency axes
are drawn in rpm and Hz on request.
"""

from __future__ import annotations

import math
from typing import Any

import httpx
import pytest

from tests.service.browser import Page, open_page, page

#: slow (CI's second step): a real chromium and a server of its own: over 10 s a file
pytestmark = pytest.mark.slow

__all__ = ["page"]

SPIN = "rotation.omega0.value"


def _posted(page: Page, path: str) -> list[dict[str, Any]]:
    """The JSON bodies the page posts to ``path``, in order (filled as it posts)."""
    bodies: list[dict[str, Any]] = []
    page.on(
        "request",
        lambda r: (
            bodies.append(r.post_data_json) if r.method == "POST" and r.url.endswith(path) else None
        ),
    )
    return bodies


def _run(page: Page) -> dict[str, Any]:
    page.evaluate("window.pipeflowViewer.state.result = null")
    page.click("#run")
    page.wait_for_function(
        "window.pipeflowViewer.state.result !== null"
        " && document.getElementById('status').textContent.startsWith('done')"
    )
    result: dict[str, Any] = page.evaluate("window.pipeflowViewer.state.result")
    return result


def _report_links(server: str, page: Page, key: str) -> None:
    """The page's report links point at the result's report, which answers."""
    for fmt, media in (("html", "text/html"), ("pdf", "application/pdf")):
        href = page.get_attribute(f"#report-{fmt}", "href")
        assert href == f"v1/results/{key}/report.{fmt}"
        assert page.is_visible(f"#report-{fmt}")
        r = httpx.get(f"{server}/{href}", timeout=120)
        assert r.status_code == 200 and r.headers["content-type"].startswith(media), r.text[:200]


def test_rpm_in_the_form_is_the_rad_per_s_result(server: str, page: Page, screenshot: Any) -> None:
    posted = _posted(page, "/v1/simulations")
    open_page(page, server + "/")
    unit = f"select[data-unit-for='{SPIN}']"
    assert page.eval_on_selector(unit, "s => [...s.options].map(o => o.value)") == [
        "rad/s",
        "rpm",
        "Hz",
    ]
    assert page.input_value(unit) == "rad/s" and page.input_value(f"input[name='{SPIN}']") == "100"
    assert page.eval_on_selector(
        "select[data-unit-for='pipe.L']", "s => [...s.options].map(o => o.value)"
    ) == ["m", "mm"]
    page.fill("input[name='modes']", "3")
    page.fill("input[name='time.t_end']", "0.05")
    page.fill("input[name='time.samples']", "51")

    page.fill(f"input[name='{SPIN}']", "3000")
    page.select_option(unit, "rpm")
    rpm = _run(page)
    assert posted[-1]["rotation"]["omega0"] == {
        "kind": "constant",
        "value": {"value": 3000, "unit": "rpm"},
    }
    assert rpm["cached"] is False
    page.locator("#spec-form").scroll_into_view_if_needed()
    page.locator(f"input[name='{SPIN}']").scroll_into_view_if_needed()
    screenshot(page, "viewer-spin-in-rpm")

    # the same physics in rad/s: the same key, answered from the cache
    page.fill(f"input[name='{SPIN}']", repr(100 * math.pi))
    page.select_option(unit, "rad/s")
    rad = _run(page)
    assert posted[-1]["rotation"]["omega0"]["value"] == 100 * math.pi
    assert rad["key"] == rpm["key"] and rad["cached"] is True
    assert "cached" in page.inner_text("#status")

    # 25 mm for the length: still that key
    page.fill("input[name='pipe.L']", "25")
    page.select_option("select[data-unit-for='pipe.L']", "mm")
    mm = _run(page)
    assert posted[-1]["pipe"]["L"] == {"value": 25, "unit": "mm"}
    assert mm["key"] == rpm["key"] and mm["cached"] is True
    link = page.get_attribute("#share-link", "href")
    assert link and "key=" in link

    # the frequency chart in Hz: omega / 2 pi of the result (the data stay rad/s)
    page.select_option("#frequency-unit", "Hz")
    page.wait_for_selector("#chart-frequency[data-unit='Hz']")
    shown = page.evaluate("window.pipeflowViewer.charts['chart-frequency'].data[1]")
    omega = mm["eigenvalues"]["modes"][0]["omega"]
    assert shown == pytest.approx([w / (2 * math.pi) for w in omega], rel=1e-12)

    _report_links(server, page, mm["key"])
    page.locator("#share").scroll_into_view_if_needed()
    screenshot(page, "viewer-report-links")
    page.goto(f"{server}/v1/results/{mm['key']}/report.html")
    assert page.title() == "pipeflow report: simulation"

    # the shared link keeps the units as typed
    page.goto("about:blank")
    open_page(page, link)
    page.wait_for_selector("#chart-tip[data-points='51']")
    assert page.input_value("input[name='pipe.L']") == "25"
    assert page.input_value("select[data-unit-for='pipe.L']") == "mm"
    assert page.input_value(unit) == "rad/s"


def test_a_unit_given_in_a_link_is_shown_and_sent_back(server: str, page: Page) -> None:
    """A link whose spec holds quantities (as another page or a person wrote it) fills the
    number and selects its unit; Run sends them as they were."""
    posted = _posted(page, "/v1/simulations")
    spec = (
        '{"pipe":{"E":7.8e9,"I":1.21e-17,"L":{"value":25,"unit":"mm"},"M1":1.884e-5,'
        '"M2":1.6485e-5},"rotation":{"omega0":{"kind":"constant","value":'
        '{"value":50,"unit":"Hz"}}},"flow":{"velocity":{"kind":"constant","value":1}},'
        '"modes":3,"time":{"t_end":0.02,"samples":21}}'
    )
    open_page(page, f"{server}/?spec={spec}")
    assert page.input_value(f"input[name='{SPIN}']") == "50"
    assert page.input_value(f"select[data-unit-for='{SPIN}']") == "Hz"
    result = _run(page)
    assert posted[-1]["rotation"]["omega0"]["value"] == {"value": 50, "unit": "Hz"}
    assert posted[-1]["pipe"]["L"] == {"value": 25, "unit": "mm"}
    assert result["status"] == "ok"
    # a value out of the schema's bounds is flagged in the unit shown: 5000 mm is 5 m
    page.fill("input[name='pipe.L']", "5000")
    assert "invalid" not in (page.get_attribute("input[name='pipe.L']", "class") or "")
    page.fill("input[name='pipe.L']", "-1")
    assert "invalid" in (page.get_attribute("input[name='pipe.L']", "class") or "")


def test_stability_page_links_the_report_and_draws_axes_in_rpm_and_hz(
    server: str, page: Page, screenshot: Any
) -> None:
    open_page(page, server + "/stability?analysis=campbell")
    page.fill("input[name='spin_range']", "0, 1500")
    page.fill("input[name='points']", "61")
    page.click("#run")
    page.wait_for_function(
        "window.pipeflowStability.state.result !== null"
        " && document.getElementById('job-status').textContent.startsWith('done')"
    )
    key = page.evaluate("window.pipeflowStability.state.key")
    _report_links(server, page, key)
    assert page.eval_on_selector("#spin-axis-unit", "s => [...s.options].map(o => o.value)") == [
        "rad/s",
        "rpm",
        "Hz",
    ]
    page.select_option("#spin-axis-unit", "rpm")
    page.select_option("#frequency-axis-unit", "Hz")
    img = "img[data-plot='campbell']"
    page.wait_for_function(
        f'(() => {{ const i = document.querySelector("{img}");'
        " return i && i.src.includes('spin_unit=rpm') && i.src.includes('frequency_unit=Hz')"
        " && i.complete && i.naturalWidth > 0; })()",
        timeout=120_000,
    )
    src = page.get_attribute(img, "src")
    assert src is not None
    svg = httpx.get(f"{server}/{src}", timeout=120)
    assert svg.status_code == 200
    assert "[rpm]" in svg.text and "[Hz]" in svg.text and "[rad/s]" not in svg.text
    png = page.get_attribute(f"figure:has({img}) figcaption a", "href") or ""
    assert png.endswith(".png?spin_unit=rpm&frequency_unit=Hz")
    page.locator("#share").scroll_into_view_if_needed()
    screenshot(page, "stability-report-links-rpm-axes")
