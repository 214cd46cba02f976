"""Fixtures for the service tests: apps with temporary data directories."""

from __future__ import annotations

import glob
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Annotated, Any

import pytest
from fastapi import APIRouter, Depends, Query, Response
from fastapi.responses import JSONResponse
from fastapi.testclient import TestClient

from pipeflow.schema.simulation import PAPER_EXAMPLE
from service.deps import RunnerDep, StoreDep
from service.http.identity import principal
from service.http.responses import job_document
from service.keys import keyed
from service.launch import free_port
from service.main import create_app
from service.orchestration import run_sync, submit_job
from service.settings import Settings
from tests.service.kinds_for_tests import SLEEP, SleepSpec

#: a small, fast simulation (3 modes, 101 samples) for API tests
SMALL: dict[str, Any] = {
    "pipe": PAPER_EXAMPLE["pipe"],
    "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
    "flow": {"velocity": {"kind": "polynomial", "coefficients": [0.0, 0.4]}},
    "modes": 3,
    "time": {"t_end": 0.2, "samples": 101},
}

TERMINAL = ("succeeded", "failed", "cancelled")


def test_router() -> APIRouter:
    """Endpoints over the test kind, written the way a real kind's endpoints are."""
    router = APIRouter(prefix="/test")

    @router.post("/sleep")
    async def sleep_now(
        spec: SleepSpec,
        runner: RunnerDep,
        store: StoreDep,
        who: Annotated[str, Depends(principal)],
        refresh: Annotated[bool, Query()] = False,
    ) -> Response:
        return await run_sync(runner, store, keyed(SLEEP, spec), refresh, principal=who)

    @router.post("/sleep-jobs", status_code=202)
    async def sleep_job(
        spec: SleepSpec,
        runner: RunnerDep,
        store: StoreDep,
        who: Annotated[str, Depends(principal)],
    ) -> JSONResponse:
        job = await submit_job(runner, store, keyed(SLEEP, spec), False, who)
        key = job.key
        doc = job_document(job)
        doc = {k: (v.isoformat() if hasattr(v, "isoformat") else v) for k, v in doc.items()}
        return JSONResponse(doc, 202, {"Location": f"/v1/jobs/{key}"})

    return router


test_router.__test__ = False  # type: ignore[attr-defined]


def make_client(tmp: Any, **overrides: Any) -> TestClient:
    settings = Settings(data_dir=tmp, **{"workers": 1, **overrides})
    app = create_app(settings)
    app.include_router(test_router())
    return TestClient(app, raise_server_exceptions=False)


def wait_ready(client: TestClient, timeout: float = 60.0) -> None:
    end = time.monotonic() + timeout
    while client.get("/readyz").status_code != 200:
        assert time.monotonic() < end, "workers did not start"
        time.sleep(0.05)


def wait_job(
    client: TestClient,
    key: str,
    until: Callable[[dict[str, Any]], bool] | None = None,
    timeout: float = 60.0,
) -> dict[str, Any]:
    """Poll GET /v1/jobs/{key} until ``until(job)`` (default: a terminal status)."""
    until = until or (lambda job: job["status"] in TERMINAL)
    end = time.monotonic() + timeout
    while True:
        job = client.get(f"/v1/jobs/{key}").json()
        if until(job):
            return job
        assert time.monotonic() < end, f"job stuck: {job}"
        time.sleep(0.05)


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """An app with 2 workers and room for 8 queued computations."""
    with make_client(tmp_path_factory.mktemp("data"), workers=2, queue_size=8) as c:
        wait_ready(c)
        yield c


@pytest.fixture(scope="module")
def tight(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """One worker, no queue, a 2 s runtime limit, fast progress checks."""
    with make_client(
        tmp_path_factory.mktemp("tight"),
        workers=1,
        queue_size=0,
        job_timeout_s=2.0,
        progress_interval_s=0.02,
        retry_after_s=3,
    ) as c:
        wait_ready(c)
        c.app.state.runner.watchdog_grace_s = 0.5  # type: ignore[attr-defined]
        yield c


# -- PostgreSQL --------------------------------------------------------------------------------

#: Debian's PostgreSQL binaries (the ``postgres`` fixture skips where there are none)
PG_BIN = sorted(glob.glob("/usr/lib/postgresql/*/bin"))


def _as_postgres(*args: str) -> None:
    subprocess.run(["runuser", "-u", "postgres", "--", *args], check=True, capture_output=True)


@pytest.fixture(scope="module")
def postgres() -> Iterator[str]:
    """A PostgreSQL cluster in a temp dir on a free port; yields its SQLAlchemy URL."""
    if not PG_BIN or shutil.which("runuser") is None:
        pytest.skip("PostgreSQL is not installed (apt-get install postgresql; .ci/run does)")
    bin_dir = Path(PG_BIN[-1])
    data = Path(tempfile.mkdtemp(prefix="pipeflow-pg-"))
    shutil.chown(data, "postgres", "postgres")
    port = free_port()
    _as_postgres(str(bin_dir / "initdb"), "-D", str(data), "-A", "trust", "-U", "postgres")
    _as_postgres(
        str(bin_dir / "pg_ctl"),
        "-D",
        str(data),
        "-o",
        f"-p {port} -k {data} -c listen_addresses=127.0.0.1 -c max_connections=200",
        "-l",
        str(data / "log"),
        "-w",
        "start",
    )
    try:
        yield f"postgresql+psycopg://postgres@127.0.0.1:{port}/postgres"
    finally:
        stop = [str(bin_dir / "pg_ctl"), "-D", str(data), "-m", "immediate", "stop"]
        subprocess.run(["runuser", "-u", "postgres", "--", *stop], check=False, capture_output=True)
        shutil.rmtree(data, ignore_errors=True)
