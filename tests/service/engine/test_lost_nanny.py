"""The embedded cluster after Dask closed a nanny whose worker was slow to come back.

A nanny restarts its worker when the process dies (the watchdog's kill), but Dask's
cluster closes the nanny itself once no worker of that name registered again within
``distributed.deploy.lost-worker-timeout`` (15 s): under load (a restart took 38 s at load
average 15) the cluster was left with no worker for good, and the synchronous request
after the watchdog test's silent job waited forever.  Here the timeout is 0 s, so the
cluster closes the nanny while its worker restarts (a process spawn and the numerical
stack's import take seconds), every time.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable
from typing import Any

import dask
import pytest
from fastapi.testclient import TestClient

from tests.service.conftest import make_client, wait_ready

pytestmark = pytest.mark.slow  # a worker restart each (CI's second step)

#: the lost-worker timeout that makes the cluster close a restarting worker's nanny
CLOSE_AT_ONCE = {"distributed.deploy.lost-worker-timeout": "0s"}


def _until(cond: Callable[[], bool], timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end, f"no {what} within {timeout} s"
        time.sleep(0.05)


def _kill_worker(c: TestClient) -> None:
    runner = c.app.state.runner  # type: ignore[attr-defined]
    pid = c.portal.call(runner.call, os.getpid)  # type: ignore[union-attr]
    os.kill(pid, signal.SIGKILL)
    _until(lambda: runner.workers == 0, 60, "removal of the killed worker")


def _post(c: TestClient, spec: dict[str, Any], timeout: float = 120) -> Any:
    """POST /test/sleep in a thread: a request that hangs fails the test, not the run."""
    out: list[Any] = []
    thread = threading.Thread(target=lambda: out.append(c.post("/test/sleep", json=spec)))
    thread.daemon = True
    thread.start()
    thread.join(timeout)
    assert out, f"the synchronous request did not return within {timeout} s"
    return out[0]


def test_closed_nanny_is_started_again(tmp_path: Any) -> None:
    """The runner gives the cluster its worker back and the next request is computed."""
    with make_client(tmp_path, workers=1, queue_size=0) as c, dask.config.set(CLOSE_AT_ONCE):
        wait_ready(c)
        runner = c.app.state.runner  # type: ignore[attr-defined]
        cluster = runner._cluster
        before = dict(cluster.workers)
        _kill_worker(c)
        _until(lambda: runner.nannies_restored >= 1, 60, "replacement of the closed nanny")
        assert all(nanny.status.name in ("closing", "closed") for nanny in before.values())
        resp = _post(c, {"seconds": 0.01, "tag": "after-nanny"})
        assert resp.status_code == 200, resp.text
        assert resp.json()["slept"] == 0.01
        # the replacement's worker registers in its own time: at load ~5 (a CI run beside
        # other work) the request above was answered while cluster.workers was still empty
        _until(
            lambda: set(cluster.workers) == set(cluster.worker_spec) == set(before),
            60,
            "the replacement nanny in the cluster's workers",
        )
        assert runner.nannies_restored == 1  # one replacement, not one per resync


def test_no_worker_for_good_answers_503(tmp_path: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """Whatever leaves the embedded cluster without a worker, a synchronous request is
    answered 503 with Retry-After after ``embedded_no_worker_grace_s``, not held forever;
    its job stays accepted and is computed once a worker is back."""
    with make_client(tmp_path, workers=1, queue_size=0) as c, dask.config.set(CLOSE_AT_ONCE):
        wait_ready(c)
        runner = c.app.state.runner  # type: ignore[attr-defined]
        restore = runner._restore_nannies
        monkeypatch.setattr(runner, "_restore_nannies", lambda: None)  # the loss stays
        runner.embedded_no_worker_grace_s = 1.0
        _kill_worker(c)
        resp = _post(c, {"seconds": 0.01, "tag": "no-worker"})
        assert resp.status_code == 503, resp.text
        assert resp.headers["content-type"] == "application/problem+json"
        assert resp.headers["retry-after"] == str(c.app.state.settings.retry_after_s)  # type: ignore[attr-defined]
        assert "no compute worker" in resp.json()["detail"]
        assert runner.in_flight == 1  # accepted: the flight goes on
        monkeypatch.setattr(runner, "_restore_nannies", restore)
        _until(lambda: runner.in_flight == 0, 120, "the accepted job's computation")
        again = _post(c, {"seconds": 0.01, "tag": "no-worker"})
        assert again.status_code == 200 and again.headers["x-cache"] == "HIT", again.text
