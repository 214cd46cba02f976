"""Fixtures shared by the test packages: a live server and a headless browser."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
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


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """Headless chromium (playwright ``Browser``); skipped locally, failed in CI, if absent.

    One per test module, not per session: while playwright's sync API is open its event
    loop counts as running in this thread, so a later module's ``asyncio.run`` in the same
    xdist worker would fail ("cannot be called from a running event loop")."""
    with chromium() as b:
        yield b


#: screenshots taken in this run, listed at the end of pytest's report
_SCREENSHOTS: list[Path] = []


@pytest.fixture
def screenshot(tmp_path_factory: pytest.TempPathFactory) -> Callable[[Any, str], Path]:
    """``screenshot(page, name)`` saves a PNG of the playwright ``page`` under the run's
    temporary directory (``<basetemp>/screenshots/<name>.png``, not the repo) and returns
    its path; pytest's summary lists every one."""
    folder = tmp_path_factory.getbasetemp() / "screenshots"

    def take(page: Any, name: str) -> Path:
        folder.mkdir(exist_ok=True)
        path = folder / f"{name}.png"
        page.screenshot(path=str(path))
        _SCREENSHOTS.append(path)
        return path

    return take


#: test files that take the longest in one process (the reader of README.md's and docs/'s
#: blocks, page by page on one server: 60-140 s by the machine's load), handed out first:
#: pytest-xdist's ``--dist loadfile`` gives files to its processes in collection order, and
#: collected last (tests/ sorts after its packages) this one ran alone at the end of the run
#: while the other process sat idle
HEAVIEST_FIRST = ("tests/test_readme.py",)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Move the :data:`HEAVIEST_FIRST` files' tests to the front, the rest in their order
    (a stable sort, the same in every xdist process, as xdist requires)."""
    items.sort(key=lambda item: not item.nodeid.startswith(HEAVIEST_FIRST))


def pytest_terminal_summary(terminalreporter: Any) -> None:
    if _SCREENSHOTS:
        terminalreporter.write_sep("-", "screenshots (browser tests)")
        for path in _SCREENSHOTS:
            terminalreporter.write_line(str(path))
