"""The durable job queue and the per-client quotas (issue 22: defect 4, Access), with the
app's real engine (an embedded Dask worker), real servers and real signals.

An asynchronous job is a promise to run later: it is accepted (202) into the store's
durable queue up to ``max_queued_jobs``, dispatched as the worker frees up, in order and
fairly between clients; a synchronous request past capacity and a full queue are 503 with
Retry-After; a client over a quota is 429 with Retry-After.  Before the queue, every
``POST .../jobs`` past ``workers + queue_size`` was a 503.
"""

from __future__ import annotations

import re
import signal
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient

from service.store import Store
from tests.service.conftest import SMALL, TERMINAL, make_client, wait_job, wait_ready
from tests.service.processes import kill_group, server
from tests.service.processes import wait_job as wait_http_job


class _Principal:
    """Stands for the API-key authentication: ``X-Test-Principal`` becomes the request's
    ``state.principal`` (what :func:`service.http.identity.principal` reads)."""

    def __init__(self, app: Any) -> None:
        self.app = app

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] == "http":
            for name, value in scope["headers"]:
                if name == b"x-test-principal":
                    scope["state"] = {**scope.get("state", {}), "principal": value.decode()}
        await self.app(scope, receive, send)


@pytest.fixture(scope="module")
def one(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """One worker, no room beyond it for synchronous requests, no fast lane; each test
    sets the queue's bound and the quotas it needs on the runner's settings (read at
    every request) and uses principals of its own (the quotas count the store's rows)."""
    settings: dict[str, Any] = dict(
        workers=1, queue_size=0, fast_lane_threads=0, progress_interval_s=0.05, retry_after_s=3
    )
    c = make_client(tmp_path_factory.mktemp("queue"), **settings)
    c.app.add_middleware(_Principal)
    with c:
        wait_ready(c)
        yield c


@pytest.fixture
def c(one: TestClient, monkeypatch: pytest.MonkeyPatch) -> TestClient:
    """:func:`one` with its settings restored after the test."""
    runner = one.app.state.runner  # type: ignore[attr-defined]
    for name in ("max_queued_jobs", "quota_queued_jobs", "quota_concurrent_jobs"):
        monkeypatch.setattr(runner.settings, name, getattr(runner.settings, name))
    monkeypatch.setattr(
        runner.settings, "quota_cost_per_minute", runner.settings.quota_cost_per_minute
    )
    return one


def _set(c: TestClient, **values: Any) -> None:
    for name, value in values.items():
        setattr(c.app.state.runner.settings, name, value)  # type: ignore[attr-defined]


def _post(c: TestClient, who: str = "alice", **spec: Any) -> httpx.Response:
    return c.post("/test/sleep-jobs", json=spec, headers={"X-Test-Principal": who})


def _job(c: TestClient, who: str = "alice", **spec: Any) -> str:
    resp = _post(c, who, **spec)
    assert resp.status_code == 202, resp.text
    key: str = resp.json()["key"]
    return key


def _gate(c: TestClient, who: str = "gate") -> str:
    """A 30 s job holding the only worker (until DELETE), so the jobs after it wait."""
    key = _job(c, who, seconds=30, tag=f"gate-{time.monotonic()}")
    wait_job(c, key, lambda j: j["progress"] > 0 or j["status"] in TERMINAL)
    return key


def _store(c: TestClient) -> Store:
    store: Store = c.app.state.store  # type: ignore[attr-defined]
    return store


def _started(c: TestClient, keys: list[str]) -> list[str]:
    """``keys`` in the order their computations started."""
    records = {k: _store(c).get_job(k) for k in keys}
    return sorted(keys, key=lambda k: records[k].started)  # type: ignore[union-attr]


@pytest.mark.slow  # thirteen jobs through one worker: 3-10 s
def test_jobs_past_capacity_wait_in_the_queue_and_run_in_order(c: TestClient) -> None:
    """Twelve distinct jobs sent to a replica with room for one computation: all are
    accepted (202; before the queue the second and later were 503s), all run once, in the
    order they were sent."""
    runner = c.app.state.runner  # type: ignore[attr-defined]
    before = runner.dispatched
    gate = _gate(c)
    keys = [_job(c, seconds=0.02, tag=f"q{i}") for i in range(12)]
    assert {c.get(f"/v1/jobs/{k}").json()["status"] for k in keys} == {"queued"}
    assert _store(c).waiting_jobs() == 12
    c.delete(f"/v1/jobs/{gate}")
    for key in keys:
        job = wait_job(c, key)
        assert job["status"] == "succeeded" and job["attempts"] == 1, job
    assert _started(c, keys) == keys
    assert runner.dispatched - before == 13


def test_clients_take_turns_for_the_worker(c: TestClient) -> None:
    """Alice queues four jobs, then Bob two: with one worker they alternate (a0 b0 a1 b1
    a2 a3): Bob does not wait behind Alice's backlog."""
    gate = _gate(c)
    alice = [_job(c, "alice-t", seconds=0.02, tag=f"a{i}") for i in range(4)]
    bob = [_job(c, "bob-t", seconds=0.02, tag=f"b{i}") for i in range(2)]
    assert _store(c).get_job(bob[0]).principal == "bob-t"  # type: ignore[union-attr]
    c.delete(f"/v1/jobs/{gate}")
    for key in alice + bob:
        assert wait_job(c, key)["status"] == "succeeded"
    a, b = alice, bob
    assert _started(c, alice + bob) == [a[0], b[0], a[1], b[1], a[2], a[3]]


def _is_problem(resp: httpx.Response, status: int, slug: str, retry_after: str | None) -> None:
    assert resp.status_code == status, resp.text
    assert resp.headers["content-type"] == "application/problem+json"
    assert resp.json()["type"].endswith("/" + slug)
    if retry_after is not None:
        assert resp.headers["retry-after"] == retry_after


def test_a_full_queue_and_a_synchronous_request_past_capacity_are_503(c: TestClient) -> None:
    _set(c, max_queued_jobs=2)
    gate = _gate(c)
    queued = [_job(c, seconds=0.02, tag=f"f{i}") for i in range(2)]
    full = _post(c, seconds=0.02, tag="f2")
    _is_problem(full, 503, "saturated", "3")
    assert "queue is full" in full.json()["detail"]
    assert c.get("/v1/jobs/" + "0" * 64).status_code == 404  # nothing half-written
    # the same job again joins it: no room needed
    assert _post(c, seconds=0.02, tag="f0").status_code == 202
    # a synchronous request past workers + queue_size (1 + 0) is a 503 as before
    _is_problem(c.post("/test/sleep", json={"seconds": 0.02, "tag": "s"}), 503, "saturated", "3")
    c.delete(f"/v1/jobs/{gate}")
    for key in queued:
        assert wait_job(c, key)["status"] == "succeeded"
    assert _post(c, seconds=0.02, tag="f2").status_code == 202  # room again


def test_queue_and_concurrency_quotas_answer_429(c: TestClient) -> None:
    """quota_queued_jobs = 2 and quota_concurrent_jobs = 1: Alice's third waiting job and
    her synchronous request while her job computes are 429 with Retry-After; Bob's quota
    is his own."""
    _set(c, quota_queued_jobs=2, quota_concurrent_jobs=1)
    gate = _gate(c, "alice-q")
    waiting = [_job(c, "alice-q", seconds=0.02, tag=f"w{i}") for i in range(2)]
    over = _post(c, "alice-q", seconds=0.02, tag="w2")
    _is_problem(over, 429, "quota", "3")
    assert "quota_queued_jobs" in over.json()["detail"]
    assert "'alice-q'" in over.json()["detail"]
    bob = _job(c, "bob-q", seconds=0.02, tag="b")
    sync = c.post(
        "/test/sleep",
        json={"seconds": 0.02, "tag": "s"},
        headers={"X-Test-Principal": "alice-q"},
    )
    _is_problem(sync, 429, "quota", "3")
    assert "quota_concurrent_jobs" in sync.json()["detail"]
    c.delete(f"/v1/jobs/{gate}")
    for key in [*waiting, bob]:
        assert wait_job(c, key)["status"] == "succeeded"


def test_cost_per_minute_quota_answers_429_until_the_window_moves(c: TestClient) -> None:
    """quota_cost_per_minute = 1.5 (the test kind has no estimate: each computation costs
    1, a whole bound): Alice's first computation passes, her second is 429 with a
    Retry-After of about the minute left in the window; a cached repeat costs nothing and
    Bob has his own minute."""
    _set(c, quota_cost_per_minute=1.5)
    alice = {"X-Test-Principal": "alice-c"}
    first = c.post("/test/sleep", json={"seconds": 0.02, "tag": "c1"}, headers=alice)
    assert first.status_code == 200, first.text
    second = c.post("/test/sleep", json={"seconds": 0.02, "tag": "c2"}, headers=alice)
    _is_problem(second, 429, "quota", None)
    assert 55 <= int(second.headers["retry-after"]) <= 60
    assert "quota_cost_per_minute" in second.json()["detail"]
    assert _post(c, "alice-c", seconds=0.02, tag="c3").status_code == 429  # jobs count too
    again = c.post("/test/sleep", json={"seconds": 0.02, "tag": "c1"}, headers=alice)
    assert again.status_code == 200 and again.headers["x-cache"] == "HIT"
    bob = c.post(
        "/test/sleep", json={"seconds": 0.02, "tag": "c2"}, headers={"X-Test-Principal": "bob-c"}
    )
    assert bob.status_code == 200, bob.text


def test_the_cost_of_a_request_is_its_estimate_over_its_bound() -> None:
    """job_cost is Computation.estimate's units / bound (here the paper's example, a small
    fraction) and 1 for a kind without an estimate."""
    from pipeflow.computations.registry import COMPUTATIONS
    from service.keys import keyed
    from service.orchestration import job_cost
    from tests.service.kinds_for_tests import SLEEP, SleepSpec

    sim = COMPUTATIONS["simulation"]
    request = sim.request.model_validate(SMALL)
    cost = sim.estimate(request)  # type: ignore[misc]
    assert cost is not None and 0 < cost.units < cost.bound
    assert job_cost(keyed(sim, request)) == cost.units / cost.bound
    assert job_cost(keyed(SLEEP, SleepSpec(seconds=1))) == 1.0


# -- real servers ------------------------------------------------------------------------

#: about 2-6 s of RK4 on this machine (quiet to loaded): holds the one worker while the
#: others wait (6 s of simulated time finished before the five were posted on the quiet
#: machine)
SLOW_JOB = {
    "pipe": SMALL["pipe"],
    "modes": 10,
    "method": "rk4",
    "time": {"t_end": 18.0, "samples": 101},
}
ONE_SLOT = {"PIPEFLOW_WORKERS": "1", "PIPEFLOW_QUEUE_SIZE": "0", "PIPEFLOW_FAST_LANE_THREADS": "0"}


def _small(i: int) -> dict[str, Any]:
    return {**SMALL, "initial": {"u0": 0.001 * (i + 1)}}


@pytest.mark.slow  # real servers SIGKILLed and restarted, 15-30 s
def test_queued_jobs_survive_a_sigkill_of_the_server(tmp_path: Path) -> None:
    """Five jobs wait behind a slow one on a one-slot server (202 each; before the queue:
    503); the server and its worker are SIGKILLed; a server restarted on the same data
    directory runs all six, the waiting ones in their first attempt."""
    env = {"PIPEFLOW_DATA_DIR": str(tmp_path), **ONE_SLOT}
    with server(tmp_path / "a.log", **env) as (proc, url):
        slow = httpx.post(f"{url}/v1/jobs", json=SLOW_JOB, timeout=30).json()["key"]
        wait_http_job(url, slow, lambda j: j["status"] == "running")
        posted = [httpx.post(f"{url}/v1/jobs", json=_small(i), timeout=30) for i in range(5)]
        assert [r.status_code for r in posted] == [202] * 5, [r.text for r in posted]
        waiting = [r.json()["key"] for r in posted]
        states = {httpx.get(f"{url}/v1/jobs/{k}", timeout=10).json()["status"] for k in waiting}
        assert states == {"queued"}
        kill_group(proc, signal.SIGKILL)

    with server(tmp_path / "b.log", **env) as (_, url):
        for key in waiting:
            job = wait_http_job(url, key)
            assert job["status"] == "succeeded" and job["attempts"] == 1, job
        assert wait_http_job(url, slow)["status"] == "succeeded"


@pytest.mark.slow  # two real servers, 15-30 s
def test_two_replicas_sharing_one_store_never_both_run_a_queued_job(tmp_path: Path) -> None:
    """Two one-slot replicas on one SQLite file; twelve jobs sent to them alternately:
    every job runs once (attempts 1), each was taken from the queue by exactly one replica
    (the replicas' "dispatching" log lines name each key once over both logs), and both
    replicas took some."""
    env = {"PIPEFLOW_DATA_DIR": str(tmp_path), **ONE_SLOT}
    logs = [tmp_path / "a.log", tmp_path / "b.log"]
    with server(logs[0], **env) as (_, url_a), server(logs[1], **env) as (_, url_b):
        keys = []
        for i in range(12):
            url = (url_a, url_b)[i % 2]
            resp = httpx.post(f"{url}/v1/jobs", json=_small(i), timeout=30)
            assert resp.status_code == 202, resp.text
            keys.append(resp.json()["key"])
        for key in keys:
            job = wait_http_job(url_a, key)
            assert job["status"] == "succeeded" and job["attempts"] == 1, job
    store = Store(tmp_path / "pipeflow.sqlite3", cache_max_bytes=0, memory_cache_bytes=0)
    takers = {store.get_job(k).dispatcher for k in keys}  # type: ignore[union-attr]
    assert len(takers) == 2, takers
    dispatched = [
        m.group(1)
        for log in logs
        for m in re.finditer(r"dispatching simulation job ([0-9a-f]{64})", log.read_text())
    ]
    assert sorted(dispatched) == sorted(keys)


def test_a_computation_that_ends_leaves_a_drained_queue_unread(tmp_path: Path) -> None:
    """Once the dispatcher found nothing waiting (with slots to spare), a computation that
    ends does not make it read the queue again (a thread hop and a query per cold
    request); a job that waited for the slot is still taken the moment a computation
    ends, without waiting for the dispatcher's poll."""
    with make_client(tmp_path, workers=1, queue_size=2, fast_lane_threads=0) as c:
        wait_ready(c)
        runner = c.app.state.runner  # type: ignore[attr-defined]
        store = runner.store
        runner.poll_s = 120.0  # after its current wait, the dispatcher sleeps past the test
        deadline = time.monotonic() + 30
        while not runner._drained:
            assert time.monotonic() < deadline, "the dispatcher never found the queue drained"
            time.sleep(0.05)
        time.sleep(1.0)  # the wait begun with the old poll interval (<= 0.5 s) has ended
        reads: list[int] = []
        claim_waiting = store.claim_waiting

        def spy(*args: Any, **kw: Any) -> Any:
            reads.append(1)
            return claim_waiting(*args, **kw)

        store.claim_waiting = spy
        assert c.post("/test/sleep", json={"seconds": 0.01, "tag": "drained"}).status_code == 200
        time.sleep(0.3)
        assert reads == []  # without the drained queue: one read when the computation ended
        # the slot taken by a synchronous run: a job queued now waits, and is taken when
        # that run ends (the poll is 120 s away)
        with ThreadPoolExecutor(1) as pool:
            busy = pool.submit(c.post, "/test/sleep", json={"seconds": 1.0, "tag": "busy"})
            while not runner.in_flight:
                time.sleep(0.01)
            queued = c.post("/test/sleep-jobs", json={"seconds": 0.01, "tag": "waits"})
            assert queued.status_code == 202
            key = queued.json()["key"]
            assert store.get_job(key).waiting
            assert busy.result().status_code == 200
        assert wait_job(c, key, timeout=20)["status"] == "succeeded"
        assert reads  # the queue was read again once the slot was free
