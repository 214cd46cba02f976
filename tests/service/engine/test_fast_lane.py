"""The fast lane: small computations in a thread of the API process, with the same job
record, lease, result and runtime limit as on a worker; switched off by a setting."""

from __future__ import annotations

import os
import socket
import time
from typing import Any

import pytest
from fastapi.testclient import TestClient

from pipeflow.computations.registry import COMPUTATIONS, run_time_simulation
from tests.service.conftest import SMALL, make_client, wait_job, wait_ready

#: a closed-form (constant flow and spin) simulation: estimated at a few milliseconds
LTI: dict[str, Any] = {**SMALL, "flow": {"velocity": {"kind": "constant", "value": 0.4}}}


def _runner(c: TestClient) -> Any:
    return c.app.state.runner  # type: ignore[attr-defined]


@pytest.fixture(scope="module")
def lane(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """One worker, the lane on (one thread) for estimates up to 0.5 s, a 1 s limit."""
    with make_client(
        tmp_path_factory.mktemp("lane"),
        workers=1,
        fast_lane_threads=1,
        fast_lane_max_s=0.5,
        job_timeout_s=1.0,
        progress_interval_s=0.02,
    ) as c:
        wait_ready(c)
        _runner(c).watchdog_grace_s = 0.3
        yield c


def test_the_simulation_estimate() -> None:
    request = COMPUTATIONS["simulation"].request
    lti = run_time_simulation(request.model_validate(LTI))
    assert lti is not None and lti < 0.01
    assert run_time_simulation(request.model_validate(SMALL)) is None  # time-variant
    assert run_time_simulation(request.model_validate({**LTI, "method": "rk4"})) is None
    big = run_time_simulation(
        request.model_validate({**LTI, "modes": 40, "time": {"samples": 20001}})
    )
    assert big is not None and big > 0.05  # beyond the default fast_lane_max_s


def test_a_small_computation_runs_in_the_lane_with_its_record(lane: TestClient) -> None:
    runner = _runner(lane)
    before = runner.lane_runs
    resp = lane.post("/v1/simulations", json=LTI)
    assert resp.status_code == 200 and resp.headers["x-cache"] == "MISS"
    assert runner.lane_runs == before + 1
    key = resp.json()["key"]
    job = runner.store.get_job(key)
    # the record as a worker leaves it: one attempt, its lease released, on this process
    assert job.status == "succeeded" and job.attempts == 1 and job.owner is None
    assert job.worker == f"{socket.gethostname()}:{os.getpid()}"
    assert lane.post("/v1/simulations", json=LTI).headers["x-cache"] == "HIT"
    # a time-variant run of a solver that does not meter its work (cma: 10 ms, within the
    # fixture's 1 s limit on a loaded machine, which rk4's 100 ms were not) has no
    # estimate: a worker runs it; with magnus (auto's choice) it is metered: the lane runs
    # it, under the allowance (test_lane_metered*.py)
    assert lane.post("/v1/simulations", json={**SMALL, "method": "cma"}).status_code == 200
    assert runner.lane_runs == before + 1
    assert lane.post("/v1/simulations", json=SMALL).status_code == 200
    assert runner.lane_runs == before + 2 and runner.lane_handoffs == 0
    # a job (202) takes the lane too, and its result is stored
    other = {**LTI, "initial": {"u0": 0.004}}
    key = lane.post("/v1/jobs", json=other).json()["key"]
    assert wait_job(lane, key)["status"] == "succeeded"
    assert runner.lane_runs == before + 3
    assert lane.get(f"/v1/results/{key}").status_code == 200


def test_an_overrun_in_the_lane_fails_its_job_and_spares_the_process(lane: TestClient) -> None:
    """A computation that never reports progress past the limit (1 s) plus grace: its job
    fails with the reason (no SIGKILL of the API process); the lane's thread stays busy
    until the computation returns, and new small work goes to a worker meanwhile."""
    runner = _runner(lane)
    before = runner.lane_runs
    spec = {"seconds": 3.0, "report": False, "estimate_s": 0.01, "tag": "overrun"}
    started = time.monotonic()
    resp = lane.post("/test/sleep", json=spec)
    assert resp.status_code == 422 and "runtime limit" in resp.text, resp.text
    assert resp.headers["content-type"] == "application/problem+json"
    assert time.monotonic() - started < 2.9  # answered when the job failed, not at the end
    assert runner.lane_runs == before + 1
    quick = lane.post("/test/sleep", json={"seconds": 0.01, "estimate_s": 0.01, "tag": "q"})
    assert quick.status_code == 200
    assert runner.lane_runs == before + 1  # the lane's one thread was busy: a worker ran it
    deadline = time.monotonic() + 10
    while runner._lane_busy and time.monotonic() < deadline:
        time.sleep(0.05)
    assert runner._lane_busy == 0
    again = lane.post("/test/sleep", json={"seconds": 0.01, "estimate_s": 0.01, "tag": "r"})
    assert again.status_code == 200 and runner.lane_runs == before + 2


def test_the_lane_respects_the_cooperative_limit(lane: TestClient) -> None:
    spec = {"seconds": 5.0, "estimate_s": 0.01, "tag": "coop"}
    resp = lane.post("/test/sleep", json=spec)
    assert resp.status_code == 422 and "runtime limit" in resp.text, resp.text


def test_the_setting_turns_the_lane_off(tmp_path: Any) -> None:
    with make_client(tmp_path, workers=1, fast_lane_threads=0) as c:
        wait_ready(c)
        resp = c.post("/v1/simulations", json={**LTI, "initial": {"u0": 0.003}})
        assert resp.status_code == 200
        runner = _runner(c)
        assert runner.lane_runs == 0
        job = runner.store.get_job(resp.json()["key"])
        assert job.worker.startswith("tcp://")  # a Dask worker's address


def test_identical_lane_requests_compute_once(lane: TestClient) -> None:
    """Twenty identical small requests at once: the first writes the record leased to its
    lane computation; the others join that flight (or, when one of them wrote the record
    first, the lane claims it as a worker would): one computation, one attempt."""
    from concurrent.futures import ThreadPoolExecutor

    runner = _runner(lane)
    computations, lane_runs = runner.computations, runner.lane_runs
    body = {**LTI, "initial": {"u0": 0.0021}}
    with ThreadPoolExecutor(20) as pool:
        responses = list(pool.map(lambda _: lane.post("/v1/simulations", json=body), range(20)))
    assert [r.status_code for r in responses] == [200] * 20
    assert runner.computations == computations + 1 and runner.lane_runs == lane_runs + 1
    docs = [r.json() for r in responses]
    assert all(d["tip_displacement"] == docs[0]["tip_displacement"] for d in docs)
    job = runner.store.get_job(docs[0]["key"])
    assert job.status == "succeeded" and job.attempts == 1 and job.generation == 1


def test_the_lookup_and_the_lane_run_share_one_thread_hop(
    lane: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A cold request the lane will run looks the store up in the lane's thread, not in a
    thread hop of its own; a result found stored there is a HIT that writes nothing (no
    job record, nothing computed), as the route's own lookup was."""
    import threading

    from service.keys import keyed

    runner = _runner(lane)
    store = runner.store
    lookups: list[tuple[str, str]] = []
    get_result = store.get_result

    def spy(key: str, **kw: Any) -> bytes | None:
        # a lookup, not the read of a finished job's body to answer it (Runner._body,
        # remember=False): under load (2 cores at load ~4) the answer sometimes came from
        # the job's record, and that read, in a to_thread hop, failed this test
        if kw.get("remember", True):
            lookups.append((key, threading.current_thread().name))
        return get_result(key, **kw)

    monkeypatch.setattr(store, "get_result", spy)
    lane_runs = runner.lane_runs
    miss = lane.post("/v1/simulations", json={**LTI, "initial": {"u0": 0.0031}})
    assert miss.status_code == 200 and miss.headers["x-cache"] == "MISS"
    key = miss.json()["key"]
    assert runner.lane_runs == lane_runs + 1
    assert [name.startswith("fast-lane") for k, name in lookups if k == key] == [True]
    # a result stored by someone else (another replica, a worker), not in the hit cache
    spec = {**LTI, "initial": {"u0": 0.0032}}
    computation = COMPUTATIONS["simulation"]
    other = keyed(computation, computation.request.model_validate(spec)).key
    stored = get_result(key)
    assert stored is not None
    store.put_result(other, "simulation", stored)
    hit = lane.post("/v1/simulations", json=spec)
    assert hit.status_code == 200 and hit.headers["x-cache"] == "HIT"
    assert hit.json() == {**miss.json(), "key": other, "cached": True}
    assert [name.startswith("fast-lane") for k, name in lookups if k == other] == [True]
    assert store.get_job(other) is None  # a hit is no write
    assert runner.lane_runs == lane_runs + 1 and not runner.is_active(other)


def test_a_look_up_run_wakes_the_event_loop_only_when_it_ends(
    lane: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The lane's thread of a cold request that looked the store up in it does not send its
    claim to the event loop mid-run (the request waits for the answer only): the loop is
    called from the lane's thread twice per run, the future's result and the thread's
    release, not a third time for the claim."""
    import asyncio
    import threading

    calls: list[str] = []
    original = asyncio.BaseEventLoop.call_soon_threadsafe

    def spy(self: Any, *args: Any, **kw: Any) -> Any:
        calls.append(threading.current_thread().name)
        return original(self, *args, **kw)

    monkeypatch.setattr(asyncio.BaseEventLoop, "call_soon_threadsafe", spy)
    runner = _runner(lane)
    lane_runs = runner.lane_runs
    resp = lane.post("/v1/simulations", json={**LTI, "initial": {"u0": 0.0033}})
    assert resp.status_code == 200 and resp.headers["x-cache"] == "MISS"
    assert runner.lane_runs == lane_runs + 1
    assert sum(name.startswith("fast-lane") for name in calls) == 2, calls
    job = runner.store.get_job(resp.json()["key"])
    assert job.status == "succeeded" and job.attempts == 1 and job.owner is None
