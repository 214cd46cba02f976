"""Who may see and cancel a job, against a real uvicorn with its Dask worker (issue 34,
item 3; README "Access: API keys").

Three keys: alice and bob, clients, and ops, an admin key (``PIPEFLOW_ADMIN_KEY_IDS``).  A
job alice started is an unknown key to bob (404, the very answer of a key that does not
exist, for GET and DELETE alike) until bob submits the same computation, which joins her
run: bob may then follow it but not cancel it (403).  ops reads and cancels anyone's job;
alice cancels her own.  A result stays readable by any key (it is content addressed).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from pipeflow.schema.stability import PAPER_PIPE_JSON
from service.http.auth import new_key
from tests.service.processes import server

#: slow: a real server with a worker starts in 10-25 s here
pytestmark = pytest.mark.slow

ALICE, ALICE_ENTRY = new_key("alice")
BOB, BOB_ENTRY = new_key("bob")
OPS, OPS_ENTRY = new_key("ops")

#: a spin map that computes for many seconds on one worker (cancelled before its end)
LONG: dict[str, Any] = {
    "kind": "spin_map",
    "pipe": PAPER_PIPE_JSON,
    "modes": 16,
    "velocity_points": 200,
    "spin_points": 200,
    "velocity_range": [0.0, 60.0],
    "spin_range": [0.0, 1500.0],
}
ACTIVE = ("queued", "running")


def _as(key: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {key}"}


@pytest.fixture(scope="module")
def url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    tmp = tmp_path_factory.mktemp("job-access")
    with server(
        tmp / "server.log",
        ready=True,
        PIPEFLOW_DATA_DIR=str(tmp),
        PIPEFLOW_WORKERS="1",
        PIPEFLOW_AUTH_REQUIRED="true",
        PIPEFLOW_API_KEYS=f"{ALICE_ENTRY},{BOB_ENTRY},{OPS_ENTRY}",
        PIPEFLOW_ADMIN_KEY_IDS="ops",
    ) as (_, base):
        yield base


def _problem(r: httpx.Response, status: int) -> dict[str, Any]:
    assert r.status_code == status, r.text
    assert r.headers["content-type"] == "application/problem+json"
    return dict(r.json())


def _unknown(r: httpx.Response, key: str) -> None:
    """The answer of a job that does not exist, word for word."""
    doc = _problem(r, 404)
    assert doc["type"].endswith("/unknown-key") and doc["detail"] == f"no job {key}", doc


def _status(url: str, key: str, who: str) -> str:
    r = httpx.get(f"{url}/v1/jobs/{key}", headers=_as(who), timeout=10)
    assert r.status_code == 200, r.text
    return str(r.json()["status"])


def test_a_key_sees_and_cancels_its_own_jobs_only(url: str) -> None:
    accepted = httpx.post(f"{url}/v1/sweeps", json=LONG, headers=_as(ALICE), timeout=30)
    assert accepted.status_code == 202, accepted.text
    key = accepted.json()["key"]
    assert _status(url, key, ALICE) in ACTIVE

    # bob neither reads nor cancels it: the answers of a key that does not exist
    nobody = "f" * 64
    for method in ("GET", "DELETE"):
        _unknown(httpx.request(method, f"{url}/v1/jobs/{nobody}", headers=_as(BOB)), nobody)
        _unknown(httpx.request(method, f"{url}/v1/jobs/{key}", headers=_as(BOB)), key)
    _unknown(httpx.get(f"{url}/v1/jobs/{key}?wait=1", headers=_as(BOB)), key)
    assert _status(url, key, ALICE) in ACTIVE  # bob's DELETE cancelled nothing
    # the pending result does not say that someone computes it either
    doc = _problem(httpx.get(f"{url}/v1/results/{key}", headers=_as(BOB)), 404)
    assert "progress" not in doc["detail"], doc

    # bob submits the same computation: he joins her run, may follow it, not cancel it
    joined = httpx.post(f"{url}/v1/sweeps", json=LONG, headers=_as(BOB), timeout=30)
    assert joined.status_code == 202 and joined.json()["key"] == key, joined.text
    assert _status(url, key, BOB) in ACTIVE
    doc = _problem(httpx.delete(f"{url}/v1/jobs/{key}", headers=_as(BOB)), 403)
    assert doc["type"].endswith("/forbidden") and "admin key" in doc["detail"], doc
    assert _status(url, key, ALICE) in ACTIVE

    # the admin key reads it; alice cancels it; bob, who follows it, sees it cancelled
    assert _status(url, key, OPS) in ACTIVE
    r = httpx.delete(f"{url}/v1/jobs/{key}", headers=_as(ALICE))
    assert r.status_code == 200 and r.json()["status"] == "cancelled", r.text
    assert _status(url, key, BOB) == "cancelled"

    # bob's own run of another map: the admin key cancels it, alice does not see it
    mine = httpx.post(
        f"{url}/v1/sweeps", json={**LONG, "spin_points": 199}, headers=_as(BOB), timeout=30
    )
    assert mine.status_code == 202, mine.text
    other = mine.json()["key"]
    _unknown(httpx.delete(f"{url}/v1/jobs/{other}", headers=_as(ALICE)), other)
    r = httpx.delete(f"{url}/v1/jobs/{other}", headers=_as(OPS))
    assert r.status_code == 200 and r.json()["status"] == "cancelled", r.text


def test_a_result_is_readable_by_any_key(url: str) -> None:
    """Content addressed: the key is the hash of the request, so whoever can compute it may
    read it; only the job record is private."""
    spec = {
        "pipe": PAPER_PIPE_JSON,
        "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
        "modes": 6,
        "velocity_range": [0.0, 40.0],
    }
    job = httpx.post(f"{url}/v1/stability/jobs", json=spec, headers=_as(ALICE), timeout=30)
    assert job.status_code == 202, job.text
    key = job.json()["key"]
    deadline = time.monotonic() + 120
    while _status(url, key, ALICE) != "succeeded":
        assert time.monotonic() < deadline
        time.sleep(0.1)
    _unknown(httpx.get(f"{url}/v1/jobs/{key}", headers=_as(BOB)), key)
    r = httpx.get(f"{url}/v1/results/{key}", headers=_as(BOB))
    assert r.status_code == 200 and r.json()["key"] == key
