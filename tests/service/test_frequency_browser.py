"""The frequency-response page (/frequency-response) in a real headless browser (set-up and
screenshots: ``tests/conftest.py``, ``tests/service/browser.py``).

Checks: the form is the API's (its example, the README's hammer test at the tip of the
paper's pipe, prefilled); a run draws |H| on log-log axes with one marker per peak, the
phase, and a peaks table equal to the answer (243.9, 1767.8, 5034.0 rad/s with damping
ratios 0.611, 0.104, 0.037, README); the server's figures load; the shareable link reloads
the result; an unstable operating point is answered with the banner; a bad position shows
the API's message next to the field.
"""

from __future__ import annotations

from typing import Any

import pytest

from tests.service.browser import Page, open_page, page

__all__ = ["page"]


def _run(page: Page) -> dict[str, Any]:
    page.click("#run")
    page.wait_for_function(
        "window.pipeflowFrequency.state.result !== null"
        " && document.getElementById('status').textContent.startsWith('done')"
    )
    result: dict[str, Any] = page.evaluate("window.pipeflowFrequency.state.result")
    return result


def _peak_rows(page: Page) -> list[list[str]]:
    rows: list[list[str]] = page.evaluate(
        """() => [...document.querySelectorAll('#tables table')[0].tBodies[0].rows]
            .map(r => [...r.cells].map(c => c.textContent))"""
    )
    return rows


def test_hammer_test_peaks_charts_figures_and_share(
    server: str, page: Page, screenshot: Any
) -> None:
    open_page(page, server + "/frequency-response")
    assert page.input_value("input[name='flow.velocity.value']") == "5"
    assert page.input_value("input[name='response.positions']") == "0.025"
    assert page.input_value("select[name='load.kind']") == "point_force"
    result = _run(page)
    assert result["kind"] == "frequency_response" and result["unit"] == "m/N"
    peaks = result["operating_points"][0]["peaks"]
    assert [round(p["frequency"], 1) for p in peaks] == [243.9, 1767.8, 5034.0]
    assert [round(p["damping_ratio"], 3) for p in peaks] == [0.611, 0.104, 0.037]
    assert "Stable at every operating point: 3 peaks" in page.inner_text("#summary")
    rows = _peak_rows(page)
    assert len(rows) == 3
    for row, p in zip(rows, peaks, strict=True):
        assert row[2] == str(p["mode"])
        assert float(row[3]) == pytest.approx(p["frequency"], rel=1e-5)
        assert float(row[5]) == pytest.approx(p["damping_ratio"], rel=1e-5)
        assert float(row[6]) == pytest.approx(p["magnitude"][0], rel=1e-5)
    magnitude = page.locator("#chart-magnitude")
    assert magnitude.get_attribute("data-points") == str(len(result["frequencies"]))
    assert magnitude.get_attribute("data-peaks") == "3"
    assert page.locator("#chart-magnitude canvas").count() == 1
    assert page.locator("#chart-phase canvas").count() == 1
    assert "[m/N]" in page.inner_text("#magnitude-title")
    for name in ("bode", "nyquist"):
        page.wait_for_function(
            f"(() => {{ const i = document.querySelector(\"img[data-plot='{name}']\");"
            " return i && i.complete && i.naturalWidth > 0; })()",
            timeout=120_000,
        )
    page.locator("#results").scroll_into_view_if_needed()
    screenshot(page, "frequency-response-hammer")
    link = page.get_attribute("#share-link", "href")
    assert link and "key=" + result["key"] in link
    page.goto("about:blank")
    open_page(page, link)
    page.wait_for_selector("#tables table")
    assert page.inner_text("#status").startswith("loaded result " + result["key"][:12])
    assert _peak_rows(page) == rows


def test_unstable_point_banner_and_bad_position(server: str, page: Page) -> None:
    open_page(page, server + "/frequency-response")
    page.fill("input[name='flow.velocity.value']", "40")  # beyond v_cr = 27.69 m/s
    page.fill("input[name='frequencies.count']", "200")
    result = _run(page)
    assert result["stable"] is False
    summary = page.locator("#summary")
    assert summary.inner_text().startswith("Unstable: 1 of 1 operating points grow")
    assert "ok" not in (summary.get_attribute("class") or "")
    assert "unstable operating point" in page.inner_text("#warnings")
    page.fill("input[name='response.positions']", "0.03")
    page.click("#run")
    slot = page.locator("[data-error-for='response.positions']")
    slot.wait_for(state="visible")
    assert "outside (0, L = 0.025 m]" in slot.inner_text()
    assert "invalid" in (page.get_attribute("input[name='response.positions']", "class") or "")
