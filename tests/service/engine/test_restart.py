"""Restart: a real uvicorn server is SIGKILLed and restarted on the same data directory.

The stored result is served after the restart, and a job accepted before the kill
finishes after it (it is re-enqueued from the SQLite job table).
"""

from __future__ import annotations

import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest

from pipeflow.schema.simulation import PAPER_EXAMPLE
from tests.service.processes import kill_group, server

#: slow (SIGKILL and restart of a real server, about 20 s): run by .ci/run's second pytest step
pytestmark = pytest.mark.slow

#: about 5 s of RK4 on this machine: still queued or running when the server is killed
SLOW_JOB = {
    "pipe": PAPER_EXAMPLE["pipe"],
    "modes": 10,
    "method": "rk4",
    "time": {"t_end": 15.0, "samples": 101},
}


@contextmanager
def _server(data_dir: Path) -> Iterator[tuple[subprocess.Popen[bytes], str]]:
    with server(
        data_dir / "server.log", ready=False, PIPEFLOW_DATA_DIR=str(data_dir), PIPEFLOW_WORKERS="1"
    ) as running:
        yield running


def _kill(proc: subprocess.Popen[bytes]) -> None:
    kill_group(proc)  # the group we started: server and workers


def test_sigkill_and_restart(tmp_path: Path) -> None:
    with _server(tmp_path) as (proc, url):
        sim = httpx.post(f"{url}/v1/simulations", json=PAPER_EXAMPLE, timeout=120)
        assert sim.status_code == 200, sim.text
        assert sim.headers["x-cache"] == "MISS"
        key = sim.json()["key"]
        accepted = httpx.post(f"{url}/v1/jobs", json=SLOW_JOB, timeout=30)
        assert accepted.status_code == 202
        job_key = accepted.json()["key"]
        state = httpx.get(f"{url}/v1/jobs/{job_key}", timeout=10).json()["status"]
        assert state in ("queued", "running")
        _kill(proc)

    with _server(tmp_path) as (_, url):
        served = httpx.get(f"{url}/v1/results/{key}", timeout=30)
        assert served.status_code == 200
        assert served.json()["tip_displacement"] == sim.json()["tip_displacement"]
        again = httpx.post(f"{url}/v1/simulations", json=PAPER_EXAMPLE, timeout=30)
        assert again.headers["x-cache"] == "HIT"

        end = time.monotonic() + 120
        while True:
            job = httpx.get(f"{url}/v1/jobs/{job_key}", timeout=10).json()
            if job["status"] not in ("queued", "running"):
                break
            assert time.monotonic() < end, f"job did not finish after restart: {job}"
            time.sleep(0.2)
        assert job["status"] == "succeeded", job
        result = httpx.get(f"{url}/v1/results/{job_key}", timeout=30)
        assert result.status_code == 200 and result.json()["method"] == "rk4"
