"""Fixtures of the client tests: the client against the real app, in-process."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from pipeflow_client import Client
from tests.service.conftest import make_client, wait_ready


@pytest.fixture(scope="module")
def service(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[TestClient]:
    """An app with one worker and a data directory of its own per test module: the
    transport of :func:`sdk_client`."""
    with make_client(tmp_path_factory.mktemp(request.module.__name__.rpartition(".")[2])) as tc:
        wait_ready(tc)
        yield tc


@pytest.fixture
def sdk_client(service: TestClient) -> Iterator[Client]:
    """pipeflow_client.Client talking to :func:`service` in-process (TestClient as httpx)."""
    with Client(str(service.base_url), http=service) as c:
        yield c
