"""A live service for tests that need one: uvicorn in a subprocess on a free port, exactly as
deployed, and Debian's chromium driven by playwright.

Used by the browser tests, the generated-client test and the README-examples test.  Tests
that need chromium or playwright skip locally when they are absent; in CI (``CI`` set) they
fail instead, so CI never silently skips them (``.ci/run`` installs both).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import pytest

from service.launch import ROOT, serve

__all__ = ["ROOT", "chromium", "need", "uvicorn_server"]

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
    "--disable-sync",
]


def need(condition: bool, reason: str) -> None:
    """Skip (locally) or fail (in CI) unless ``condition``."""
    if condition:
        return
    if os.environ.get("CI"):
        pytest.fail(f"{reason} (CI must run this test: see .ci/run)")
    pytest.skip(reason)


@contextmanager
def uvicorn_server(data_dir: Path, log: Path, **env: str) -> Iterator[str]:
    """``uvicorn service.main:app`` on a free port of 127.0.0.1 with its data in
    ``data_dir`` and one worker (:func:`service.launch.serve`); yields the base URL once
    ``/readyz`` answers 200, fails the test with the server's log if it never does."""
    settings = {"PIPEFLOW_DATA_DIR": str(data_dir), "PIPEFLOW_WORKERS": "1", **env}
    with ExitStack() as stack:
        try:
            server = stack.enter_context(serve(log, env=settings, timeout_s=60))
        except RuntimeError as exc:
            pytest.fail(str(exc))
        yield server.url


@contextmanager
def chromium() -> Iterator[Any]:
    """A headless chromium (playwright ``Browser``); skips or fails as :func:`need` says."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:  # pragma: no cover - depends on the machine
        need(False, "playwright is not installed (pip install playwright)")
    need(os.path.exists(CHROMIUM), f"{CHROMIUM} is absent (apt-get install -y chromium)")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            yield b
        finally:
            b.close()
