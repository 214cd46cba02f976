"""A job the fast lane accepted survives a SIGKILL of its server: the lane writes the
record already leased to its computation (one transaction), so a restart finds it
running under a dead lease, takes it over once the lease is stale and finishes it on a
worker.  Real processes: ``uvicorn`` serving the app with the test routes, killed with
its whole group (server and workers)."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import httpx
import pytest
from fastapi import FastAPI

from service.launch import free_port
from service.main import create_app
from service.settings import Settings
from tests.service.processes import (
    FAST_RECOVERY,
    job_record,
    kill_group,
    spawn,
    wait_http,
    wait_job,
)

#: slow (two real servers started, one killed, a stale lease waited for: 15-30 s)
pytestmark = pytest.mark.slow


def create_app_with_test_routes() -> FastAPI:
    """``uvicorn --factory``: the service (settings from the environment) plus the test
    kinds' routes (:func:`tests.service.conftest.test_router`)."""
    from tests.service.conftest import test_router

    app = create_app(Settings())
    app.include_router(test_router())
    return app


def _serve(data_dir: Path, log: Path) -> tuple[subprocess.Popen[bytes], str]:
    port = free_port()
    proc = spawn(
        [
            sys.executable,
            "-m",
            "uvicorn",
            "--factory",
            f"{__name__}:create_app_with_test_routes",
            "--port",
            str(port),
        ],
        log,
        PIPEFLOW_DATA_DIR=str(data_dir),
        PIPEFLOW_WORKERS="1",
        PIPEFLOW_LOG_LEVEL="INFO",
        **FAST_RECOVERY,
    )
    url = f"http://127.0.0.1:{port}"
    wait_http(f"{url}/readyz", proc)
    return proc, url


def test_a_lane_job_survives_a_killed_server(tmp_path: Path) -> None:
    # a computation the lane takes (its estimate says 10 ms; it runs 4 s, reporting
    # progress): accepted with 202, then the server and its workers are SIGKILLed
    spec = {"seconds": 4.0, "estimate_s": 0.01, "tag": "lane-restart"}
    proc, url = _serve(tmp_path / "data", tmp_path / "first.log")
    try:
        accepted = httpx.post(f"{url}/test/sleep-jobs", json=spec, timeout=30)
        assert accepted.status_code == 202, accepted.text
        key = accepted.json()["key"]
        # a job is accepted into the store's durable queue (a row: it survives any
        # restart) and dispatched at once; the lane takes it: running on the API process
        # itself (the lane's worker name is host:pid)
        assert accepted.json()["status"] in ("queued", "running"), accepted.json()
        job = wait_job(url, key, lambda j: j["progress"] > 0, timeout=30)
        assert job["status"] == "running" and job["attempts"] == 1
        record = job_record(tmp_path / "data", key)
        assert record.worker is not None and record.worker.endswith(f":{proc.pid}"), record
    finally:
        kill_group(proc, signal.SIGKILL)

    proc, url = _serve(tmp_path / "data", tmp_path / "second.log")
    try:
        job = wait_job(url, key, timeout=90)
        assert job["status"] == "succeeded", job
        # the second attempt took the dead lane's lease over, on a worker of the new server
        assert job["attempts"] == 2, job
        assert "attempt 1 on" in (job["last_retry_reason"] or ""), job
        assert "stopped heartbeating" in job["last_retry_reason"], job
        record = job_record(tmp_path / "data", key)
        assert record.worker is not None and record.worker.startswith("tcp://"), record
        result = httpx.get(f"{url}/v1/results/{key}", timeout=30)
        assert result.status_code == 200 and result.json()["tag"] == "lane-restart"
    finally:
        kill_group(proc, signal.SIGKILL)
