"""The supports in the stability page's form, in a real headless browser (issue 31): the
form generated from the OpenAPI document offers each end's support as a choice, and a
pinned-pinned paper pipe loses stability by divergence (set-up: ``tests/conftest.py``,
``tests/service/browser.py``)."""

from __future__ import annotations

from typing import Any

import pytest

from tests.service.browser import Page, open_page, page

#: slow (CI's second step): a real chromium and a server of its own
pytestmark = pytest.mark.slow

__all__ = ["page"]


def test_the_form_offers_the_supports_and_a_spool_diverges(
    server: str, page: Page, screenshot: Any
) -> None:
    open_page(page, server + "/stability")
    options = page.eval_on_selector_all(
        "select[name='pipe.supports.x0'] option", "os => os.map(o => o.value)"
    )
    assert options == ["clamped", "pinned", "sliding", "free"]
    page.click("details[data-group='pipe.supports'] > summary")
    page.select_option("select[name='pipe.supports.x0']", "pinned")
    page.select_option("select[name='pipe.supports.xL']", "pinned")
    page.click("#run")
    page.wait_for_function(
        "window.pipeflowStability.state.result !== null"
        " && document.getElementById('job-status').textContent.startsWith('done')"
    )
    result = page.evaluate("window.pipeflowStability.state.result")
    assert result["mechanism"] == "divergence"
    # the paper's pipe pinned at both ends: u = pi at about 9.5 m/s (spin 100 rad/s)
    assert 9.0 < result["critical_velocity"] < 10.0
    assert "divergence" in page.inner_text("#tables")
    screenshot(page, "stability-supported-pipe")
