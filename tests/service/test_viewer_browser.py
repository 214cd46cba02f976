"""The viewer in a real headless browser (Debian's chromium driven by playwright).

The service runs as a uvicorn subprocess on a free port, exactly as deployed.  Checks: the
page loads with the paper's example, a run completes, the three charts show data, the
share link reloads the result by its key, and a bad input shows the API's message next to
the field.  Locally the test is skipped when chromium or playwright is absent; in CI
(``CI`` set) it fails instead, so CI never silently skips it.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import httpx
import pytest

if TYPE_CHECKING:
    from playwright.sync_api import Page


@pytest.fixture
def page(browser: Any) -> Iterator[Page]:
    context = browser.new_context(viewport={"width": 1100, "height": 900})
    pg = context.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    pg.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    pg.set_default_timeout(60_000)
    yield pg
    context.close()
    # failed HTTP requests (the 422 of the bad-input test) log a console error; scripts must not
    assert not [e for e in errors if "Failed to load resource" not in e], errors


def _points(page: Page, chart: str) -> int:
    return int(page.get_attribute(f"#{chart}", "data-points") or 0)


def test_run_the_papers_example_and_share_it(server: str, page: Page) -> None:
    page.goto(server + "/")
    assert page.input_value("input[name='pipe.E']") == "7.8e9"
    assert page.input_value("input[name='flow.velocity.coefficients']") == "0, 0.4"
    page.click("#run")
    page.wait_for_selector("#chart-tip[data-points='2001']")
    assert "done (ok" in page.inner_text("#status")
    for chart in ("chart-damping", "chart-frequency"):
        assert _points(page, chart) == 201
        assert page.locator(f"#{chart} canvas").count() == 1
    # the charts hold the result's numbers: the fundamental frequency near 284 rad/s
    omega0 = page.evaluate("window.pipeflowViewer.charts['chart-frequency'].data[1][0]")
    assert 280 < omega0 < 290

    link = page.get_attribute("#share-link", "href")
    assert link and "key=" in link
    key = page.evaluate("window.pipeflowViewer.state.key")
    page.goto("about:blank")
    page.goto(link)
    page.wait_for_selector("#chart-tip[data-points='2001']")
    assert key[:12] in page.inner_text("#status")
    assert page.input_value("input[name='pipe.E']") == "7.8e9"
    csv_href = page.get_attribute("#csv-history", "href")
    assert csv_href is not None
    text = httpx.get(f"{server}/{csv_href}", timeout=10).text
    assert text.startswith("t [s],tip_displacement [m]")

    # a link whose spec is mangled still loads the result by its key
    page.goto("about:blank")
    page.goto(f"{server}/?key={key}&spec=%7Bbroken")
    page.wait_for_selector("#chart-tip[data-points='2001']")
    assert page.inner_text("#status").startswith("loaded result " + key[:12])


def test_bad_input_shows_the_api_message_next_to_the_field(server: str, page: Page) -> None:
    page.goto(server + "/")
    page.fill("input[name='pipe.L']", "-0.025")
    page.fill("input[name='flow.velocity.coefficients']", "0, fast")
    page.click("#run")
    slot = page.locator("[data-error-for='pipe.L']")
    slot.wait_for(state="visible")
    # the message is the API's own (pydantic's bound check, passed through problem+json)
    assert "greater than 0" in slot.inner_text()
    assert "invalid" in (page.get_attribute("input[name='pipe.L']", "class") or "")
    coeff = page.locator("[data-error-for='flow.velocity.coefficients']")
    assert "valid number" in coeff.inner_text()
    assert page.inner_text("#status") == "Invalid input"
    assert _points(page, "chart-tip") == 0
    # fixing the fields clears the messages on the next run
    page.fill("input[name='pipe.L']", "0.025")
    page.fill("input[name='flow.velocity.coefficients']", "0, 0.4")
    page.fill("input[name='modes']", "4")
    page.click("#run")
    page.wait_for_selector("#chart-tip[data-points='2001']")
    assert page.locator("[data-error-for='pipe.L']").inner_text() == ""
