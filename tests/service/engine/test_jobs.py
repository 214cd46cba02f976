"""Jobs: submission, status and progress, idempotence, cancel, runtime limit, saturation."""

from __future__ import annotations

import time
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.service.conftest import SMALL, make_client, wait_job, wait_ready


def test_job_lifecycle(client: TestClient) -> None:
    body = {**SMALL, "initial": {"u0": 0.005}}
    resp = client.post("/v1/jobs", json=body)
    assert resp.status_code == 202, resp.text
    job = resp.json()
    key = job["key"]
    assert resp.headers["location"] == f"/v1/jobs/{key}"
    assert job["status"] in ("queued", "running", "succeeded")
    assert job["kind"] == "simulation"
    done = wait_job(client, key)
    assert done["status"] == "succeeded", done
    assert done["progress"] == 1.0
    assert done["created"] <= done["started"] <= done["finished"]
    assert done["result"] == f"/v1/results/{key}"
    result = client.get(done["result"])
    assert result.status_code == 200 and result.json()["key"] == key

    # the job id is the parameter hash: the same run through the sync endpoint is a hit
    sync = client.post("/v1/simulations", json=body)
    assert sync.headers["x-cache"] == "HIT" and sync.json()["key"] == key

    # resubmitting is idempotent and reuses the result
    runner = client.app.state.runner  # type: ignore[attr-defined]
    before = runner.computations
    again = client.post("/v1/jobs", json=body)
    assert again.status_code == 202 and again.json()["status"] == "succeeded"
    assert runner.computations == before


def test_job_failure_keeps_reason(client: TestClient) -> None:
    body = {**SMALL, "method": "rk4", "options": {"step": 0.5}}
    key = client.post("/v1/jobs", json=body).json()["key"]
    job = wait_job(client, key)
    assert job["status"] == "failed"
    assert job["error"]["status"] == 422
    assert job["error"]["errors"][0]["field"] == "options.step"
    assert client.get(f"/v1/results/{key}").status_code == 404


def test_unknown_job_404(client: TestClient) -> None:
    for method in ("GET", "DELETE"):
        resp = client.request(method, "/v1/jobs/" + "a" * 64)
        assert resp.status_code == 404
        assert resp.headers["content-type"] == "application/problem+json"


def test_job_validation_422(client: TestClient) -> None:
    resp = client.post("/v1/jobs", json={**SMALL, "modes": 0})
    assert resp.status_code == 422
    assert resp.json()["errors"][0]["field"] == "modes"


def _sleep_job(c: TestClient, **spec: Any) -> str:
    resp = c.post("/test/sleep-jobs", json=spec)
    assert resp.status_code == 202, resp.text
    key: str = resp.json()["key"]
    return key


def test_cancel_running_job(tight: TestClient) -> None:
    key = _sleep_job(tight, seconds=30, tag="cancel")
    running = wait_job(tight, key, lambda j: j["status"] == "running" and j["progress"] > 0)
    assert 0 < running["progress"] < 1
    resp = tight.delete(f"/v1/jobs/{key}")
    assert resp.status_code == 200 and resp.json()["status"] == "cancelled"
    # the worker stops at its next progress check and frees the only slot
    _wait_idle(tight)
    job = tight.get(f"/v1/jobs/{key}").json()
    assert job["status"] == "cancelled" and job["finished"] is not None
    assert tight.delete(f"/v1/jobs/{key}").status_code == 200  # idempotent
    # a cancelled job is run again when resubmitted
    again = tight.post("/test/sleep-jobs", json={"seconds": 30, "tag": "cancel"}).json()
    assert again["key"] == key and again["status"] in ("queued", "running")
    tight.delete(f"/v1/jobs/{key}")
    _wait_idle(tight)


def _wait_idle(c: TestClient) -> None:
    runner = c.app.state.runner  # type: ignore[attr-defined]
    end = time.monotonic() + 20
    while runner.in_flight:
        assert time.monotonic() < end, "a computation still occupies the worker"
        time.sleep(0.05)


def test_resubmit_while_cancelled_run_stops(tight: TestClient) -> None:
    key = _sleep_job(tight, seconds=30, tag="resubmit")
    wait_job(tight, key, lambda j: j["status"] == "running")
    assert tight.delete(f"/v1/jobs/{key}").json()["status"] == "cancelled"
    again = tight.post("/test/sleep-jobs", json={"seconds": 30, "tag": "resubmit"})
    assert again.status_code == 202
    assert again.json()["status"] in ("queued", "running")
    assert tight.delete(f"/v1/jobs/{key}").json()["status"] == "cancelled"
    _wait_idle(tight)


def test_cancel_finished_job_409(tight: TestClient) -> None:
    key = _sleep_job(tight, seconds=0.01, tag="done")
    assert wait_job(tight, key)["status"] == "succeeded"
    resp = tight.delete(f"/v1/jobs/{key}")
    assert resp.status_code == 409
    assert resp.headers["content-type"] == "application/problem+json"


def test_runtime_limit_fails_job(tight: TestClient) -> None:
    """A job past the runtime limit (2 s here) ends failed, with the reason."""
    key = _sleep_job(tight, seconds=30, tag="limit")
    job = wait_job(tight, key)
    assert job["status"] == "failed"
    assert job["error"]["type"].endswith("/runtime-limit")
    assert "runtime limit" in job["error"]["detail"]


@pytest.mark.slow  # over 8 s (CI's second step)
def test_watchdog_fails_silent_job(tight: TestClient) -> None:
    """A worker that never reports progress is stopped by the watchdog, and the pool recovers."""
    key = _sleep_job(tight, seconds=60, report=False, tag="silent")
    job = wait_job(tight, key)
    assert job["status"] == "failed"
    assert "runtime limit" in job["error"]["detail"]
    quick = tight.post("/test/sleep", json={"seconds": 0.01, "tag": "after-watchdog"})
    assert quick.status_code == 200, (quick.text, tight.get("/v1/jobs/" + key).json())


def test_saturated_503(tight: TestClient) -> None:
    key = _sleep_job(tight, seconds=30, tag="busy")
    try:
        busy = tight.post("/v1/simulations", json=SMALL)
        assert busy.status_code == 503
        assert busy.headers["content-type"] == "application/problem+json"
        assert busy.headers["retry-after"] == "3"
        ready = tight.get("/readyz")
        assert ready.status_code == 503 and ready.headers["retry-after"] == "3"
        # a job is a promise to run later: it waits in the durable queue (issue 22)
        queued = tight.post("/v1/jobs", json=SMALL)
        assert queued.status_code == 202 and queued.json()["status"] == "queued", queued.text
        # joining the computation already in flight needs no new slot
        assert (
            tight.post("/test/sleep-jobs", json={"seconds": 30, "tag": "busy"}).status_code == 202
        )
    finally:
        tight.delete(f"/v1/jobs/{key}")
    assert wait_job(tight, queued.json()["key"])["status"] == "succeeded"
    _wait_idle(tight)
    assert tight.post("/v1/simulations", json=SMALL).status_code == 200


@pytest.mark.slow  # over 8 s (CI's second step)
def test_post_after_delete_never_answers_a_dead_job(
    tmp_path: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The cancel race, forced: a POST of a spec right after DELETE of its running job, with
    the cancelled run stopping while the POST is being answered.  The answer is a job that
    runs (queued or running, then succeeded), never 202 ``cancelled`` with nothing running.

    The interleaving is made deterministic through the store seam: the worker checks the
    cancel flag only every second (``progress_interval_s``), and while the POST is handled
    the job record is read only once the cancelled run has stopped.  Before the fix the POST
    shared the stopping run, read the record after it ended cancelled, and answered that.
    """
    with make_client(tmp_path, workers=1, queue_size=2, progress_interval_s=1.0) as c:
        wait_ready(c)
        runner = c.app.state.runner  # type: ignore[attr-defined]
        store = c.app.state.store  # type: ignore[attr-defined]
        spec = {"seconds": 2.5, "tag": "race"}
        key = _sleep_job(c, **spec)
        wait_job(c, key, lambda j: j["status"] == "running")
        assert c.delete(f"/v1/jobs/{key}").json()["status"] == "cancelled"
        old = runner._flights[key].task  # still running: its next cancel check is ~1 s away
        assert not old.done()
        read = store.get_job

        def get_job_after_the_old_run(k: str) -> Any:
            while not old.done():
                time.sleep(0.01)
            return read(k)

        monkeypatch.setattr(store, "get_job", get_job_after_the_old_run)
        again = c.post("/test/sleep-jobs", json=spec)
        monkeypatch.setattr(store, "get_job", read)
        assert old.done() and old.exception() is not None  # it ended cancelled
        assert again.status_code == 202
        assert again.json()["status"] in ("queued", "running"), again.json()
        assert runner.is_active(key)
        assert wait_job(c, key)["status"] == "succeeded"
