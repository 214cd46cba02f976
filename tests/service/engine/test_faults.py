"""Faults in embedded mode, with real processes and signals: nothing accepted is lost.

- SIGKILL of one Dask worker mid-job: only that job is retried (attempts = 2, with the
  reason), the job on the other worker is untouched (attempts = 1).
- SIGKILL of the uvicorn server (the process only, not its group): no worker process
  outlives it by more than a few seconds, and the job finishes after a restart.
- Two replicas on one SQLite file, one SIGKILLed mid-job: the other finishes the job.
- The data directory on a full tmpfs: 507 problem+json with Retry-After, /readyz 503,
  then recovery by itself once space is back.
- A damaged or zero-length database file: the server refuses to start and says what to do.
"""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from pipeflow.computations.registry import COMPUTATIONS
from pipeflow.schema.simulation import PAPER_EXAMPLE
from service.keys import keyed
from service.launch import free_port
from tests.service.conftest import SMALL, make_client, wait_job, wait_ready
from tests.service.processes import (
    kill_group,
    live_group_members,
    server,
    spawn,
)
from tests.service.processes import wait_job as wait_http_job

#: about 2 s of RK4 on this machine (unloaded): running when the fault strikes
SLOW_JOB = {
    "pipe": PAPER_EXAMPLE["pipe"],
    "modes": 10,
    "method": "rk4",
    "time": {"t_end": 6.0, "samples": 101},
}

#: heartbeat every 0.1 s, a lease without one for 2 s is dead: recoveries take seconds
FAST_RECOVERY = {"PIPEFLOW_PROGRESS_INTERVAL_S": "0.1", "PIPEFLOW_STALE_AFTER_S": "2"}


def _running(job: dict[str, Any]) -> bool:
    return job["status"] == "running" and job["progress"] > 0


@pytest.mark.slow  # real processes killed, 15-25 s
def test_sigkill_one_worker_retries_only_its_job(tmp_path: Path) -> None:
    with make_client(
        tmp_path, workers=2, queue_size=2, progress_interval_s=0.1, stale_after_s=2.0
    ) as c:
        wait_ready(c)
        keys = [
            c.post("/test/sleep-jobs", json={"seconds": 4, "tag": t}).json()["key"] for t in "ab"
        ]
        for key in keys:
            wait_job(c, key, _running)
        store = c.app.state.store  # type: ignore[attr-defined]
        victim, innocent = (store.get_job(k) for k in keys)
        assert victim.worker != innocent.worker  # one job per worker
        pids = c.portal.call(c.app.state.runner.client.run, os.getpid)  # type: ignore[attr-defined, union-attr]
        os.kill(pids[victim.worker], signal.SIGKILL)

        retried = wait_job(c, victim.key)
        untouched = wait_job(c, innocent.key)
        assert retried["status"] == "succeeded" and untouched["status"] == "succeeded"
        assert retried["attempts"] == 2
        assert "attempt 1 on " + victim.worker in retried["last_retry_reason"]
        assert "stopped heartbeating" in retried["last_retry_reason"]
        assert untouched["attempts"] == 1 and untouched["last_retry_reason"] is None
        assert c.get(f"/v1/results/{victim.key}").json()["slept"] == 4


@pytest.mark.slow  # real processes killed, 15-25 s
def test_sigkill_server_leaves_no_worker_and_job_finishes(tmp_path: Path) -> None:
    log = tmp_path / "server.log"
    overrides = {"PIPEFLOW_DATA_DIR": str(tmp_path), "PIPEFLOW_WORKERS": "2", **FAST_RECOVERY}
    with server(log, **overrides) as (proc, url):
        key = httpx.post(f"{url}/v1/jobs", json=SLOW_JOB, timeout=30).json()["key"]
        wait_http_job(url, key, _running)
        assert len(live_group_members(proc.pid)) >= 3  # the server, 2 nannies, 2 workers
        os.kill(proc.pid, signal.SIGKILL)  # the server only: its children must follow
        proc.wait(timeout=10)
        killed = time.monotonic()
        while members := live_group_members(proc.pid):
            assert time.monotonic() - killed < 5.0, f"still alive after 5 s: {members}"
            time.sleep(0.1)

    with server(log, **overrides) as (_, url):
        job = wait_http_job(url, key)
        assert job["status"] == "succeeded", job
        assert job["attempts"] == 2 and "stopped heartbeating" in job["last_retry_reason"]
        assert httpx.get(f"{url}/v1/results/{key}", timeout=30).json()["method"] == "rk4"


@pytest.mark.slow  # real processes killed, 15-25 s
def test_two_replicas_on_one_sqlite_file(tmp_path: Path) -> None:
    """Replicas share one file safely (leases): the same spec sent to both computes once,
    and a job whose replica is SIGKILLed (with its workers) is finished by the other."""
    overrides = {"PIPEFLOW_DATA_DIR": str(tmp_path), "PIPEFLOW_WORKERS": "1", **FAST_RECOVERY}
    with (
        server(tmp_path / "a.log", **overrides) as (proc_a, url_a),
        server(tmp_path / "b.log", **overrides) as (_, url_b),
    ):
        body = {**SMALL, "initial": {"u0": 0.002}}
        both = [httpx.post(f"{u}/v1/simulations", json=body, timeout=60) for u in (url_a, url_b)]
        assert [r.status_code for r in both] == [200, 200]
        assert both[0].json()["tip_displacement"] == both[1].json()["tip_displacement"]
        key = both[0].json()["key"]
        assert httpx.get(f"{url_b}/v1/jobs/{key}", timeout=10).json()["attempts"] == 1

        slow = httpx.post(f"{url_a}/v1/jobs", json=SLOW_JOB, timeout=30).json()["key"]
        job = wait_http_job(url_a, slow, _running)
        kill_group(proc_a)  # replica A and its workers
        job = wait_http_job(url_b, slow)
        assert job["status"] == "succeeded", job
        assert job["attempts"] >= 2 and "stopped heartbeating" in job["last_retry_reason"]


@pytest.fixture
def tiny_disk(tmp_path: Path) -> Iterator[Path]:
    """A 16 MB tmpfs (root can mount one), unmounted afterwards."""
    mount = tmp_path / "disk"
    mount.mkdir()
    try:
        subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=16m", "tmpfs", str(mount)],
            check=True,
            capture_output=True,
        )
    except (subprocess.CalledProcessError, FileNotFoundError) as exc:
        pytest.skip(f"cannot mount a tmpfs here (needs root): {exc}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)


def _fill(directory: Path, leave: int) -> Path:
    """Write a file that leaves ``leave`` bytes free on ``directory``'s filesystem."""
    st = os.statvfs(directory)
    filler = directory / "filler"
    with open(filler, "wb") as fh:
        fh.write(b"\0" * max(st.f_bavail * st.f_frsize - leave, 0))
    return filler


@pytest.mark.slow  # over 8 s (CI's second step)
def test_full_disk_answers_507_then_recovers(tiny_disk: Path) -> None:
    with make_client(tiny_disk, workers=1, retry_after_s=2, progress_interval_s=0.1) as c:
        wait_ready(c)
        assert c.post("/v1/simulations", json=SMALL).status_code == 200
        # room for a job record, not for a large result (about 2 MB of JSON, 1 MB stored)
        filler = _fill(tiny_disk, leave=64 * 1024)
        big = {**SMALL, "time": {"t_end": 0.2, "samples": 20001}}
        resp = c.post("/v1/simulations", json=big)
        assert resp.status_code == 507, resp.text
        assert resp.headers["content-type"] == "application/problem+json"
        assert resp.headers["retry-after"] == "2"
        assert "full" in resp.json()["detail"]
        ready = c.get("/readyz")
        assert ready.status_code == 503 and ready.json()["type"].endswith("/storage")
        # the cause, not SQLite's "OperationalError: database or disk is full" (issue 34)
        assert "the disk of the store is full" in ready.json()["detail"]
        assert "OperationalError" not in ready.text and "database or disk" not in ready.text
        assert ready.headers["retry-after"] == "2"
        # new work is refused while the store cannot write (never 500); cached results are
        # still served
        other = c.post("/v1/jobs", json={**SMALL, "initial": {"u0": 0.007}})
        assert other.status_code == 507, other.text
        assert other.headers["retry-after"] == "2"
        assert c.post("/v1/simulations", json=SMALL).headers["x-cache"] == "HIT"

        filler.unlink()  # space is back: the probe sees it, the service is ready again
        end = time.monotonic() + 30
        while c.get("/readyz").status_code != 200:
            assert time.monotonic() < end, "did not recover after space came back"
            time.sleep(0.1)
        # the job that could not store its result is failed with the reason (written as
        # soon as the store took writes again, if the disk was too full even for that)
        simulation = COMPUTATIONS["simulation"]
        big_key = keyed(simulation, simulation.request.model_validate(big)).key
        job = wait_job(c, big_key, lambda j: j["status"] != "running", timeout=10)
        assert job["status"] == "failed", job
        assert job["error"]["status"] == 507 and "could not be stored" in job["error"]["detail"]
        again = c.post("/v1/simulations", json=big)
        assert again.status_code == 200 and len(again.json()["t"]) == 20001
        assert c.get(f"/v1/jobs/{big_key}").json()["status"] == "succeeded"


def _start_refused(data_dir: Path) -> tuple[int, str]:
    log = data_dir / "server.log"
    proc = spawn(
        [sys.executable, "-m", "uvicorn", "service.main:app", "--port", str(free_port())],
        log,
        PIPEFLOW_DATA_DIR=str(data_dir),
        PIPEFLOW_WORKERS="1",
    )
    try:
        code = proc.wait(timeout=60)
    finally:
        kill_group(proc)
    return code, log.read_text()


def test_damaged_database_is_refused(tmp_path: Path) -> None:
    db = tmp_path / "pipeflow.sqlite3"
    conn = sqlite3.connect(db)
    conn.execute("CREATE TABLE filler (x BLOB)")
    conn.executemany("INSERT INTO filler VALUES (?)", [(os.urandom(3000),) for _ in range(40)])
    conn.commit()
    conn.close()
    data = bytearray(db.read_bytes())
    data[4096 * 2 : 4096 * 5] = b"\xa5" * (4096 * 3)
    db.write_bytes(bytes(data))
    code, log = _start_refused(tmp_path)
    assert code != 0
    assert "refusing to start" in log and "pipeflow.sqlite3" in log
    assert "backup" in log and ".recover" in log


def test_zero_length_database_is_refused(tmp_path: Path) -> None:
    db = tmp_path / "pipeflow.sqlite3"
    db.touch()
    code, log = _start_refused(tmp_path)
    assert code != 0
    assert "empty (0 bytes)" in log and "not reinitialised" in log
    assert db.stat().st_size == 0
