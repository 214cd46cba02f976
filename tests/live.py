"""A live service for tests that need one: uvicorn in a subprocess on a free port, exactly as
deployed, and Debian's chromium driven by playwright.

Used by the browser tests, the generated-client test and the README-examples test.  Tests
that need chromium or playwright skip locally when they are absent; in CI (``CI`` set) they
fail instead, so CI never silently skips them (``.ci/run`` installs both).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import pytest

ROOT = Path(__file__).resolve().parents[1]
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


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


@contextmanager
def uvicorn_server(data_dir: Path, log: Path, **env: str) -> Iterator[str]:
    """``uvicorn service.main:app`` on a free port of 127.0.0.1 with its data in
    ``data_dir`` and one worker; yields the base URL once ``/readyz`` answers 200."""
    port = free_port()
    environ = dict(os.environ, PIPEFLOW_DATA_DIR=str(data_dir), PIPEFLOW_WORKERS="1", **env)
    with log.open("w") as out:
        proc = subprocess.Popen(
            [sys.executable, "-m", "uvicorn", "service.main:app", "--port", str(port)],
            cwd=ROOT,
            env=environ,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                if httpx.get(url + "/readyz", timeout=2).status_code == 200:
                    break
            except httpx.TransportError:
                pass
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"uvicorn did not become ready:\n{log.read_text()}")
            time.sleep(0.1)
        yield url
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


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
