"""Requests that must not stall a real uvicorn server (issue 34): its probes answer while a
bad request is being refused.

- A unit string that pint would evaluate (``"9**9**8 mm"``: ~100 s of a core in pint's
  parser, the event loop blocked all along) is refused by the unit grammar with a 422 in
  well under the bounds below, while ``/healthz`` keeps answering.
"""

from __future__ import annotations

import copy
import threading
import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from tests.service.conftest import SMALL
from tests.service.processes import server

#: slow: a real server with a worker starts in 10-25 s here
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    tmp = tmp_path_factory.mktemp("guards-server")
    with server(tmp / "server.log", PIPEFLOW_DATA_DIR=str(tmp), PIPEFLOW_WORKERS="1") as (_, url):
        yield url


def test_a_number_expression_unit_is_refused_at_once_while_probes_answer(live: str) -> None:
    """Ten bodies with ``"unit": "9**9**8 mm"`` sent one after the other get their 422
    within 2 s each (a generous bound: it takes milliseconds; before, ~100 s each), and
    a probe sent meanwhile answers within 1 s every time (before: not until pint gave
    up).  The 422 is a problem document naming the field."""
    body: dict[str, Any] = copy.deepcopy(SMALL)
    body["pipe"]["L"] = {"value": 25, "unit": "9**9**8 mm"}
    answers: list[httpx.Response | BaseException] = []

    def send_bad_bodies() -> None:
        with httpx.Client(base_url=live, timeout=2.0) as bad:
            for _ in range(10):
                try:
                    answers.append(bad.post("/v1/simulations", json=body))
                except httpx.HTTPError as exc:
                    answers.append(exc)
                    return

    sender = threading.Thread(target=send_bad_bodies)
    with httpx.Client(base_url=live, timeout=1.0) as probe:
        sender.start()
        probes = 0
        while sender.is_alive() or probes == 0:
            assert probe.get("/healthz").status_code == 200  # a timeout fails the test
            probes += 1
            time.sleep(0.01)
    sender.join()
    assert len(answers) == 10, answers
    for resp in answers:
        assert isinstance(resp, httpx.Response), resp
        assert resp.status_code == 422
        assert resp.headers["content-type"] == "application/problem+json"
        (error,) = resp.json()["errors"]
        assert error["field"] == "pipe.L.unit"
        assert "'9**9**8 mm' is not a unit" in error["message"]
