"""Fixtures shared by the test packages: a live server and a headless browser."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from tests.live import chromium, uvicorn_server


@pytest.fixture(scope="module")
def server(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[str]:
    """The base URL of ``uvicorn service.main:app`` in a subprocess, one per test module,
    with a data directory of its own (:func:`tests.live.uvicorn_server`)."""
    name = request.module.__name__.rpartition(".")[2]
    log = tmp_path_factory.mktemp(f"{name}-log") / "uvicorn.log"
    with uvicorn_server(tmp_path_factory.mktemp(f"{name}-data"), log) as url:
        yield url


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    """Headless chromium (playwright ``Browser``); skipped locally, failed in CI, if absent."""
    with chromium() as b:
        yield b
