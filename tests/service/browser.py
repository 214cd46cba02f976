"""The browser tests' page: a playwright page of the shared headless chromium.

The live server (``server``), the browser (``browser``) and ``screenshot`` (PNGs under the
run's temporary directory, listed in pytest's summary) are fixtures of ``tests/conftest.py``
(:mod:`tests.live`).  A test fails if a page script raises or logs an error.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
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
    pg.wait_for_function = csp_safe_wait(pg)  # type: ignore[method-assign]
    yield pg
    context.close()
    # failed HTTP requests (a 422 of a bad-input test) log a console error; scripts must not
    assert not [e for e in errors if "Failed to load resource" not in e], errors


def open_page(page: Page, url: str) -> None:
    """Load a viewer page and wait until its schema-generated form is ready."""
    page.goto(url)
    page.wait_for_selector("#run:not([disabled])")


def csp_safe_wait(page: Page, default_timeout_ms: float = 60_000) -> Callable[..., Any]:
    """``page.wait_for_function`` that works under the pages' Content-Security-Policy.

    Playwright's own ``wait_for_function`` compiles its predicate with ``eval`` inside the
    page while polling, which ``script-src 'self'`` (no ``'unsafe-eval'``) refuses: an
    EvalError and a console error of Playwright's making, not the page's.  This one polls
    from Python with ``page.evaluate`` (the DevTools protocol's call, which the policy does
    not govern), so the pages keep their real policy and any violation of their own code
    still fails the test through the console check of :func:`page`."""

    def wait_for_function(
        expression: str,
        *,
        arg: Any = None,
        timeout: float | None = None,
        polling: float | str | None = None,
    ) -> Any:
        interval = polling if isinstance(polling, int | float) else 50
        deadline = time.monotonic() + (default_timeout_ms if timeout is None else timeout) / 1e3
        while True:
            value = page.evaluate(expression, arg)
            if value:
                return value
            if time.monotonic() > deadline:
                raise TimeoutError(f"wait_for_function({expression!r}) still false")
            page.wait_for_timeout(interval)

    return wait_for_function
