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

#: slow (CI's second step): a real chromium and a server of its own: over 10 s a file
pytestmark = pytest.mark.slow

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


def test_two_operating_points_from_the_form(server: str, page: Page, screenshot: Any) -> None:
    """Two operating points (v = 0 and 10 m/s at w0 = 100 rad/s) added in the form's list
    editor: the single point's flow and spin are greyed out and not sent (the API refuses
    both), the answer has one block per point, |H| is drawn as two curves with every peak
    marked (the undamped v = 0 peaks too, whose |H| the answer leaves null) and the server's
    waterfall figure loads.  Removing the points gives the single point back."""
    open_page(page, server + "/frequency-response")
    page.fill("input[name='frequencies.count']", "400")
    points = page.locator("[data-list='operating_points']")
    assert points.get_attribute("data-count") == "0"
    assert page.get_attribute("#frf-form", "data-mode") == "single"
    page.click("[data-add='operating_points']")
    # the first point is the single one as typed (v = 5 m/s, w0 = 100 rad/s)
    assert page.input_value("input[name='operating_points.0.velocity']") == "5"
    assert page.input_value("input[name='operating_points.0.omega0']") == "100"
    page.click("[data-add='operating_points']")
    page.fill("input[name='operating_points.0.velocity']", "0")
    page.fill("input[name='operating_points.1.velocity']", "10")
    assert "velocity [m/s]" in points.inner_text() and "omega0 [rad/s]" in points.inner_text()
    assert page.get_attribute("#frf-form", "data-mode") == "operating_points"
    assert page.locator("input[name='flow.velocity.value']").is_disabled()
    assert page.locator("input[name='rotation.omega0.value']").is_disabled()
    result = _run(page)
    sent = page.evaluate("JSON.parse(new URL(location.href).searchParams.get('spec'))")
    assert "flow" not in sent and "omega0" not in sent.get("rotation", {})
    assert sent["operating_points"] == [
        {"velocity": 0, "omega0": 100},
        {"velocity": 10, "omega0": 100},
    ]
    ops = result["operating_points"]
    assert [(p["velocity"], p["omega0"]) for p in ops] == [(0, 100), (10, 100)]
    assert all(len(p["peaks"]) >= 2 for p in ops)
    # v = 0 without damping: the peaks are undamped, their |H| infinite (null)
    assert {p["damping_ratio"] for p in ops[0]["peaks"]} == {0}
    assert all(p["magnitude"] == [None] for p in ops[0]["peaks"])
    magnitude = page.locator("#chart-magnitude")
    assert magnitude.get_attribute("data-scale") == "log"
    assert magnitude.get_attribute("data-series") == "4"  # two curves, two peak series
    assert magnitude.get_attribute("data-peaks") == str(sum(len(p["peaks"]) for p in ops))
    drawn = page.evaluate("window.pipeflowFrequency.state.charts['chart-magnitude'].data")
    for curve, peaks, point in ((drawn[1], drawn[2], ops[0]), (drawn[3], drawn[4], ops[1])):
        marked = [(i, y) for i, y in enumerate(peaks) if y is not None]
        assert len(marked) == len(point["peaks"])
        assert all(y == curve[i] or y > 0 for i, y in marked)
    rows = _peak_rows(page)
    assert len(rows) == sum(len(p["peaks"]) for p in ops)
    assert rows[0][0] == "0" and rows[-1][0] == "10"
    assert rows[0][6] == "∞ (undamped)"
    assert "waterfall" in result["plots"]
    page.wait_for_function(
        "[...document.querySelectorAll('#plots img')].every(i => i.complete && i.naturalWidth > 0)",
        timeout=120_000,
    )
    page.locator("#results").scroll_into_view_if_needed()
    screenshot(page, "frequency-two-operating-points")
    page.locator("img[data-plot='waterfall']").scroll_into_view_if_needed()
    screenshot(page, "frequency-two-operating-points-waterfall")
    page.click("[data-remove='operating_points.1']")
    page.click("[data-remove='operating_points.0']")
    assert page.get_attribute("#frf-form", "data-mode") == "single"
    assert page.locator("input[name='flow.velocity.value']").is_enabled()


def test_waterfall_example_loads_into_the_form(server: str, page: Page) -> None:
    """The request's named examples are offered; the waterfall one fills the list editor
    with its four operating points."""
    open_page(page, server + "/frequency-response")
    assert page.input_value("#example") == "hammer"
    page.select_option("#example", "waterfall")
    assert page.get_attribute("[data-list='operating_points']", "data-count") == "4"
    assert page.input_value("input[name='operating_points.3.velocity']") == "20"
    assert page.get_attribute("#frf-form", "data-mode") == "operating_points"
