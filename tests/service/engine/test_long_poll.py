"""Long polls on the job resource (issue 19): ``GET /v1/jobs/{key}?wait=<s>`` answers when
the job has ended (succeeded, failed, cancelled) or when the wait is over, with a real
uvicorn server and its embedded Dask worker; a job run by another replica sharing the
store is seen too.  The time bounds asserted are the requests' own waits (an answer
before a 60 s wait ended, an answer not before a 0.5 s wait ended), never a speed."""

from __future__ import annotations

import random
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient

from pipeflow_client import Client
from tests.service.conftest import SMALL, make_client, wait_ready
from tests.service.processes import server
from tests.service.processes import wait_job as wait_http_job

#: a simulation of ~1-3 s (rk4, 10 modes, 2 s of motion) and one of ~20 s
SHORT = {
    "pipe": SMALL["pipe"],
    "modes": 10,
    "method": "rk4",
    "time": {"t_end": 2.0, "samples": 101},
}
LONG = SHORT | {"time": {"t_end": 20.0, "samples": 101}}
#: one slot, no fast lane: every job goes to the worker
ONE_SLOT = {"PIPEFLOW_WORKERS": "1", "PIPEFLOW_QUEUE_SIZE": "0", "PIPEFLOW_FAST_LANE_THREADS": "0"}


@pytest.fixture(scope="module")
def url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    data = tmp_path_factory.mktemp("long-poll")
    with server(data / "server.log", PIPEFLOW_DATA_DIR=str(data), **ONE_SLOT) as (_, base):
        yield base


def _post(url: str, spec: dict[str, Any]) -> str:
    body = spec | {"initial": {"u0": 1e-3 * (1 + random.random())}}  # a new key each time
    resp = httpx.post(f"{url}/v1/jobs", json=body, timeout=30)
    assert resp.status_code == 202, resp.text
    key: str = resp.json()["key"]
    return key


def _long_poll(url: str, key: str, wait: float) -> tuple[dict[str, Any], float, float]:
    """The job document of ``GET ?wait=``, and when the request was sent and answered
    [s since the epoch, the clock the job's timestamps use]."""
    sent = time.time()
    resp = httpx.get(f"{url}/v1/jobs/{key}", params={"wait": wait}, timeout=wait + 30)
    answered = time.time()
    assert resp.status_code == 200, resp.text
    doc: dict[str, Any] = resp.json()
    return doc, sent, answered


def _epoch(stamp: str) -> float:
    from datetime import datetime

    return datetime.fromisoformat(stamp).timestamp()


def test_a_long_poll_answers_when_the_job_ends_not_after_its_wait(url: str) -> None:
    key = _post(url, SHORT)
    job, sent, answered = _long_poll(url, key, 60)
    assert job["status"] == "succeeded", job
    # answered after the job finished, and before the 60 s the request allowed were over
    assert _epoch(job["finished"]) <= answered
    assert answered - sent < 60
    # a finished job answers at once, whatever the wait: the same document
    again, sent, answered = _long_poll(url, key, 60)
    assert again["status"] == "succeeded" and again["finished"] == job["finished"]
    assert answered - sent < 60


def test_a_wait_that_ends_first_answers_with_the_current_status(url: str) -> None:
    key = _post(url, LONG)
    wait_http_job(url, key, lambda j: j["status"] == "running")
    job, sent, answered = _long_poll(url, key, 0.5)
    assert job["status"] == "running", job
    assert answered - sent >= 0.5  # held for its wait: the job had not ended
    httpx.delete(f"{url}/v1/jobs/{key}", timeout=30)


def test_a_long_poll_answers_a_cancel_at_once(url: str) -> None:
    """A waiter on a running job is answered ``cancelled`` by the DELETE, not after its
    wait (the route wakes it; the job's worker stops later)."""
    key = _post(url, LONG)
    wait_http_job(url, key, lambda j: j["status"] == "running")
    answers: list[tuple[dict[str, Any], float, float]] = []
    waiter = threading.Thread(target=lambda: answers.append(_long_poll(url, key, 60)))
    waiter.start()
    time.sleep(0.5)  # the long poll is held (not a measured time: the order of events)
    deleted = httpx.delete(f"{url}/v1/jobs/{key}", timeout=30)
    assert deleted.status_code == 200, deleted.text
    waiter.join(90)
    ((job, sent, answered),) = answers
    assert job["status"] == "cancelled", job
    assert answered - sent < 60


def test_wait_out_of_bounds_is_422_naming_it(url: str) -> None:
    key = _post(url, SHORT)
    for bad in ("61", "-1", "soon", "nan"):
        resp = httpx.get(f"{url}/v1/jobs/{key}", params={"wait": bad}, timeout=30)
        assert resp.status_code == 422, (bad, resp.text)
        assert resp.headers["content-type"].startswith("application/problem+json")
        fields = [e.get("field") for e in resp.json()["errors"]]
        assert fields == ["wait"], (bad, resp.json())


def test_the_client_waits_with_long_polls(url: str) -> None:
    """The Python client's wait (what the CLI uses) is a chain of long polls: one
    ``GET ?wait=`` per hold, no polling between them."""
    requests: list[httpx.Request] = []
    http = httpx.Client(timeout=120, event_hooks={"request": [requests.append]})
    with Client(url, http=http) as client:
        job = client.submit(SHORT | {"initial": {"u0": 1e-3 * (1 + random.random())}})
        result = client.wait_raw(job["key"])
    http.close()
    assert result["diagnostics"] is not None
    gets = [r for r in requests if r.url.path == f"/v1/jobs/{job['key']}"]
    assert gets and all(r.url.params.get("wait") == "30" for r in gets)
    assert len(gets) == 1  # ~2 s of computing: one long poll saw it end


def test_past_the_bound_of_waiters_a_long_poll_answers_at_once(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    """``max_job_waiters`` = 1: a second long poll on a running job is answered at once
    with its status while the first is held; the first is answered by the job's end."""
    with make_client(tmp_path_factory.mktemp("waiters"), max_job_waiters=1) as c:
        wait_ready(c)
        key = c.post("/test/sleep-jobs", json={"seconds": 3.0, "tag": "w"}).json()["key"]
        first: list[httpx.Response] = []
        held = threading.Thread(
            target=lambda: first.append(c.get(f"/v1/jobs/{key}", params={"wait": 60}))
        )
        held.start()
        runner = c.app.state.runner  # type: ignore[attr-defined]
        while runner.waiting == 0:  # the first long poll is held (the bound is full)
            time.sleep(0.01)
        second = _timed(c, key)
        assert second[0]["status"] in ("queued", "running")
        assert second[1] < 60  # not held: the waiters' bound was reached
        held.join(90)
        assert first[0].json()["status"] == "succeeded"
        assert runner.waiting == 0 and not runner._watches


def test_a_wait_past_the_servers_cap_is_answered_at_the_cap(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    """``max_job_wait_s`` = 0.5: ``?wait=60`` on a job that runs for 20 s is answered with
    its current status once the cap has passed, not after the job's end (nor 60 s)."""
    with make_client(tmp_path_factory.mktemp("cap"), max_job_wait_s=0.5) as c:
        wait_ready(c)
        key = c.post("/test/sleep-jobs", json={"seconds": 20.0, "tag": "cap"}).json()["key"]
        try:
            doc, took = _timed(c, key)
            assert doc["status"] in ("queued", "running")
            assert 0.4 < took < 15  # held for the cap, then answered: the job had 20 s to go
        finally:
            c.delete(f"/v1/jobs/{key}")


def _timed(c: TestClient, key: str) -> tuple[dict[str, Any], float]:
    started = time.monotonic()
    doc: dict[str, Any] = c.get(f"/v1/jobs/{key}", params={"wait": 60}).json()
    return doc, time.monotonic() - started


@pytest.mark.slow  # two real servers sharing a store: 15-40 s
def test_a_job_run_by_another_replica_ends_a_long_poll(tmp_path: Path) -> None:
    """Replica B holds a long poll on a job replica A runs (B has no flight of it): B's
    monitor reads the shared store and answers once A's run has finished."""
    env = {"PIPEFLOW_DATA_DIR": str(tmp_path), **ONE_SLOT}
    with (
        server(tmp_path / "a.log", **env) as (_, url_a),
        server(tmp_path / "b.log", **env) as (
            _,
            url_b,
        ),
    ):
        key = _post(url_a, LONG | {"time": {"t_end": 4.0, "samples": 101}})
        wait_http_job(url_a, key, lambda j: j["status"] == "running")
        job, sent, answered = _long_poll(url_b, key, 60)
        assert job["status"] == "succeeded", job
        assert _epoch(job["finished"]) <= answered and answered - sent < 60
        record = httpx.get(f"{url_a}/v1/jobs/{key}", timeout=30).json()
        assert record["finished"] == job["finished"]
    # A took it from the queue (its 202 dispatches at once), so B never drove it
    assert f"dispatching simulation job {key}" in (tmp_path / "a.log").read_text()
    assert f"job {key}" not in (tmp_path / "b.log").read_text()  # no dispatch, no recovery
