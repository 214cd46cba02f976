"""Distributed mode as local processes: the docker-compose topology without Docker.

A throwaway PostgreSQL cluster (initdb in a temp dir, run as ``postgres``), ``dask
scheduler``, 2 ``dask worker`` processes and 2 uvicorn replicas sharing both; Dask speaks
TLS only, as in docker-compose.yml (files of ``python -m service.tls``, ``DASK_CONFIG`` for
every peer, ``tls://`` addresses, ``--preload-nanny``).  Checked:

- 200 jobs submitted across both replicas all finish, none computed twice (each job
  record's ``attempts`` is 1: counted from the store, not from a replica);
- the same spec sent to both replicas at once is computed once;
- SIGKILL of the replica that accepted a running job: the job finishes anyway (the task
  finishes its own record) and nothing is recomputed;
- restart of the scheduler mid-job: the job still finishes (resubmitted when its
  heartbeat goes stale, or finished by the task that survived), nothing lost.
"""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import pytest
from sqlalchemy import create_engine, text

from service.launch import free_port
from service.tls import main as tls_main
from tests.service.conftest import SMALL
from tests.service.processes import kill_group, server, spawn, wait_http, wait_job

#: slow (PostgreSQL, a scheduler, workers and two replicas; about 75 s): .ci/run's -m slow step
pytestmark = pytest.mark.slow

#: about 2 s of RK4 on this machine (unloaded): running when the fault strikes
SLOW_JOB = {**SMALL, "modes": 10, "method": "rk4", "time": {"t_end": 6.0, "samples": 101}}
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


@dataclass
class Topology:
    db_url: str
    scheduler: subprocess.Popen[bytes]
    scheduler_port: int
    workers: list[subprocess.Popen[bytes]]
    replicas: list[tuple[subprocess.Popen[bytes], str]]
    logs: Path
    stopping: threading.Event = field(default_factory=threading.Event)

    @property
    def address(self) -> str:
        return f"tls://127.0.0.1:{self.scheduler_port}"

    @property
    def dask_env(self) -> dict[str, str]:
        """The Dask configuration of every peer: the TLS files (docker-compose.yml's way)."""
        return {"DASK_CONFIG": str(self.logs / "tls")}

    def start_worker(self, i: int) -> subprocess.Popen[bytes]:
        return spawn(
            [
                *(sys.executable, "-m", "distributed.cli.dask_worker", self.address),
                *("--nthreads", "1", "--preload-nanny", "service.engine.preload"),
                *("--no-dashboard", "--name", f"w{i}"),
            ],
            self.logs / f"worker{i}.log",
            **WORKER_ENV,
            **self.dask_env,
        )

    def supervise(self) -> None:
        """Restart workers that exit, as compose's ``restart: unless-stopped`` does (a
        ``dask worker`` exits when it loses its scheduler)."""
        while not self.stopping.wait(0.5):
            for i, proc in enumerate(self.workers):
                if proc.poll() is not None:
                    kill_group(proc)
                    self.workers[i] = self.start_worker(i)

    def start_scheduler(self) -> None:
        self.scheduler = spawn(
            [
                *(sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1"),
                *("--port", str(self.scheduler_port), "--no-dashboard"),
            ],
            self.logs / "scheduler.log",
            **self.dask_env,
        )

    def query(self, sql: str) -> Any:
        engine = create_engine(self.db_url)
        try:
            with engine.connect() as conn:
                return conn.execute(text(sql)).all()
        finally:
            engine.dispose()


@pytest.fixture(scope="module")
def topology(postgres: str, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Topology]:
    logs = tmp_path_factory.mktemp("topology")
    port = free_port()
    topo = Topology(postgres, None, port, [], [], logs)  # type: ignore[arg-type]
    tls_main([str(logs / "tls")])  # the README's and compose's command
    topo.start_scheduler()
    address = topo.address
    topo.workers = [topo.start_worker(i) for i in range(2)]
    supervisor = threading.Thread(target=topo.supervise, daemon=True)
    supervisor.start()
    settings = {
        "PIPEFLOW_DATABASE_URL": postgres,
        "PIPEFLOW_SCHEDULER_ADDRESS": address,
        "PIPEFLOW_WORKERS": "2",
        "PIPEFLOW_QUEUE_SIZE": "400",
        "PIPEFLOW_PROGRESS_INTERVAL_S": "0.2",
        "PIPEFLOW_STALE_AFTER_S": "3",
        "PIPEFLOW_DATA_DIR": str(logs),
        **topo.dask_env,
    }
    contexts = [server(logs / f"replica{i}.log", **settings) for i in range(2)]
    try:
        topo.replicas = [ctx.__enter__() for ctx in contexts]
        yield topo
    finally:
        topo.stopping.set()
        supervisor.join()
        for ctx in contexts:
            ctx.__exit__(None, None, None)
        for proc in [*topo.workers, topo.scheduler]:
            kill_group(proc)


def _post(url: str, path: str, body: dict[str, Any]) -> httpx.Response:
    return httpx.post(f"{url}{path}", json=body, timeout=120)


def test_200_jobs_across_two_replicas_compute_once(topology: Topology) -> None:
    urls = [url for _, url in topology.replicas]
    bodies = [
        {
            **SMALL,
            "modes": 2,
            "time": {"t_end": 0.05, "samples": 21},
            "initial": {"u0": 1e-3 + i * 1e-6},
        }
        for i in range(200)
    ]
    keys = []
    for i, body in enumerate(bodies):
        resp = _post(urls[i % 2], "/v1/jobs", body)
        assert resp.status_code == 202, resp.text
        keys.append(resp.json()["key"])
    assert len(set(keys)) == 200
    end = time.monotonic() + 150
    quoted = ",".join(f"'{k}'" for k in keys)
    while True:
        rows = topology.query(f"SELECT status, attempts FROM jobs WHERE key IN ({quoted})")
        if sum(status == "succeeded" for status, _ in rows) == 200:
            break
        bad = [r for r in rows if r[0] in ("failed", "cancelled")]
        assert not bad, bad
        assert time.monotonic() < end, f"{sum(r[0] == 'succeeded' for r in rows)}/200 done"
        time.sleep(0.5)
    assert sorted({attempts for _, attempts in rows}) == [1]  # none computed twice
    assert topology.query(f"SELECT count(*) FROM results WHERE key IN ({quoted})")[0][0] == 200
    # any replica serves any result
    for key in keys[:4]:
        assert httpx.get(f"{urls[1]}/v1/results/{key}", timeout=30).status_code == 200


def test_same_spec_to_both_replicas_at_once_computes_once(topology: Topology) -> None:
    body = {**SMALL, "initial": {"u0": 0.0042}}
    answers: list[httpx.Response] = []
    barrier = threading.Barrier(2)

    def call(url: str) -> None:
        barrier.wait()
        answers.append(_post(url, "/v1/simulations", body))

    threads = [threading.Thread(target=call, args=(url,)) for _, url in topology.replicas]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert [r.status_code for r in answers] == [200, 200]
    assert answers[0].json()["tip_displacement"] == answers[1].json()["tip_displacement"]
    key = answers[0].json()["key"]
    assert topology.query(f"SELECT attempts FROM jobs WHERE key = '{key}'") == [(1,)]


def test_scheduler_restart_mid_job(topology: Topology) -> None:
    url = topology.replicas[1][1]
    key = _post(url, "/v1/jobs", {**SLOW_JOB, "initial": {"u0": 0.002}}).json()["key"]
    wait_job(url, key, lambda j: j["status"] == "running")
    kill_group(topology.scheduler)
    topology.start_scheduler()
    job = wait_job(url, key, timeout=150)
    assert job["status"] == "succeeded", job
    # a fresh job after the restart runs as well, once the replica is ready again (its
    # workers reconnected: until then a synchronous request answers 503 no-worker)
    wait_http(f"{url}/readyz", timeout=150)
    fresh = _post(url, "/v1/simulations", {**SMALL, "initial": {"u0": 0.0031}})
    assert fresh.status_code == 200, fresh.text


def test_sigkill_replica_mid_job(topology: Topology) -> None:
    (proc, url_a), (_, url_b) = topology.replicas
    key = _post(url_a, "/v1/jobs", {**SLOW_JOB, "initial": {"u0": 0.003}}).json()["key"]
    wait_job(url_a, key, lambda j: j["status"] == "running")
    kill_group(proc)
    job = wait_job(url_b, key, timeout=120)
    assert job["status"] == "succeeded", job
    assert job["attempts"] == 1  # the task outlived its replica: nothing recomputed
    assert httpx.get(f"{url_b}/v1/results/{key}", timeout=30).status_code == 200
    wait_http(f"{url_b}/readyz")


def test_scheduler_speaks_tls_only(topology: Topology) -> None:
    """A peer without the set-up's certificate cannot reach the scheduler: plain TCP to its
    port is refused (the replicas and workers above all connected over TLS)."""
    from distributed import Client

    assert topology.address.startswith("tls://")
    with pytest.raises(OSError):
        Client(topology.address.replace("tls://", "tcp://"), timeout="3s")
