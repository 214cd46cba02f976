"""The browser tests' page: a playwright page of the shared headless chromium.

The live server (``server``), the browser (``browser``) and ``screenshot`` (PNGs under the
run's temporary directory, listed in pytest's summary) are fixtures of ``tests/conftest.py``
(:mod:`tests.live`).  A test fails if a page script raises or logs an error.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from playwright.sync_api import Page
else:
    Page = Any


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
    # failed HTTP requests (a 422 of a bad-input test) log a console error; scripts must not
    assert not [e for e in errors if "Failed to load resource" not in e], errors


def open_page(page: Page, url: str) -> None:
    """Load a viewer page and wait until its schema-generated form is ready."""
    page.goto(url)
    page.wait_for_selector("#run:not([disabled])")
