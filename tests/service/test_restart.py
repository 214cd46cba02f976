"""Restart: a real uvicorn server is SIGKILLed and restarted on the same data directory.

The stored result is served after the restart, and a job accepted before the kill
finishes after it (it is re-enqueued from the SQLite job table).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx

from pipeflow.schema.simulation import PAPER_EXAMPLE
from tests.live import free_port

ROOT = Path(__file__).resolve().parents[2]

#: about 5 s of RK4 on this machine: still queued or running when the server is killed
SLOW_JOB = {
    "pipe": PAPER_EXAMPLE["pipe"],
    "modes": 10,
    "method": "rk4",
    "time": {"t_end": 15.0, "samples": 101},
}


@contextmanager
def _server(data_dir: Path) -> Iterator[tuple[subprocess.Popen[bytes], str]]:
    port = free_port()
    env = {**os.environ, "PIPEFLOW_DATA_DIR": str(data_dir), "PIPEFLOW_WORKERS": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "uvicorn", "service.main:app", "--port", str(port)],
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # its own process group: the server and its workers
    )
    url = f"http://127.0.0.1:{port}"
    try:
        end = time.monotonic() + 90
        while True:
            assert proc.poll() is None, "uvicorn exited"
            try:
                if httpx.get(f"{url}/healthz", timeout=2).status_code == 200:
                    break
            except httpx.TransportError:
                pass
            assert time.monotonic() < end, "uvicorn did not start"
            time.sleep(0.1)
        yield proc, url
    finally:
        _kill(proc)


def _kill(proc: subprocess.Popen[bytes]) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)  # the group we started: server and workers
        proc.wait(timeout=30)


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
