"""A long magnus computation resumes from its checkpoint after a SIGKILL (issue 22,
defect 8): before, a job running when its server (and the workers with it) was killed
restarted from zero after recovery.

Real components: ``uvicorn`` serving the app on its embedded Dask cluster (one worker) on
a SQLite store, killed with its whole process group (server and worker) once the job's
computation has written a checkpoint and computed on past it, then a server restarted on
the same data directory.  The resumed job's result is compared with an uninterrupted
library run of the same request in this process.
"""

from __future__ import annotations

import functools
import os
import signal
import sqlite3
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec
from pipeflow.simulation import simulate
from tests.service.conftest import make_client, wait_ready
from tests.service.conftest import wait_job as wait_app_job
from tests.service.processes import kill_group, server, wait_job

#: slow (a 10-20 s computation, two real servers, a SIGKILL): CI's second step
pytestmark = pytest.mark.slow

#: pulsating flow v = 2 + sin(50 t) m/s on the paper's pipe, 10 modes, tolerance 1e-10,
#: 6 s: four attempts of 252,000 steps and 579,692 exponentials in all, ~7 s here (over
#: 1.5 s it was 509,442 exponentials before a refinement was capped at 8x, 182,370 after:
#: ~2 s, which could end before the second checkpoint)
LONG_JOB: dict[str, Any] = {
    **PAPER_EXAMPLE,
    "method": "magnus",
    "time": {"t_end": 6.0, "samples": 12001},
    "flow": {"velocity": {"kind": "harmonic", "mean": 2.0, "amplitude": 1.0, "frequency": 50.0}},
    "options": {"tolerance": 1e-10},
}
#: a checkpoint every second; heartbeats every 0.1 s, a lease without one for 2 s is dead
ENV = {
    "PIPEFLOW_WORKERS": "1",
    "PIPEFLOW_CHECKPOINT_INTERVAL_S": "1",
    "PIPEFLOW_PROGRESS_INTERVAL_S": "0.1",
    "PIPEFLOW_STALE_AFTER_S": "2",
}


def _get(url: str, path: str) -> httpx.Response:
    return httpx.get(f"{url}{path}", timeout=10)


def _checkpoints(db: Path) -> list[tuple[str, int, int, float]]:
    """The checkpoints table as the store holds it: (key, generation, size, written)."""
    conn = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=30)
    try:
        return conn.execute("SELECT key, generation, size, written FROM checkpoints").fetchall()
    finally:
        conn.close()


def test_a_killed_magnus_job_resumes_from_its_checkpoint(tmp_path: Path) -> None:
    db = tmp_path / "pipeflow.sqlite3"
    env = {"PIPEFLOW_DATA_DIR": str(tmp_path), **ENV}
    with server(tmp_path / "a.log", **env) as (proc, url):
        accepted = httpx.post(f"{url}/v1/jobs", json=LONG_JOB, timeout=30)
        assert accepted.status_code == 202, accepted.text
        key = accepted.json()["key"]
        # wait for the second checkpoint (the row is replaced in place: its written time
        # moves), so the computation is well past its start and past a checkpoint
        get = functools.partial(_get, url)
        _written(get, key, db, after=_written(get, key, db, after=0.0))
        kill_group(proc)  # server and worker, at once
    [(ck_key, generation, size, _)] = _checkpoints(db)
    assert ck_key == key and generation == 1 and 0 < size <= 64 << 20

    with server(tmp_path / "b.log", **env) as (_, url):
        job = wait_job(url, key, timeout=180)
        assert job["status"] == "succeeded", job
        assert job["attempts"] == 2, job
        result = httpx.get(f"{url}/v1/results/{key}", timeout=60).json()
    assert _checkpoints(db) == []  # deleted with the job's finish

    whole = simulate(SimulationSpec.model_validate(LONG_JOB).to_simulation())
    diag = result["diagnostics"]
    # the same steps, attempts and exponentials as the uninterrupted run (integers: equal)
    for name in ("steps", "attempts", "matrix_exponentials", "steps_order_6"):
        assert diag[name] == whole.diagnostics[name], name
    # the same states to rounding: the worker and this process run the same operations
    # (bit-identical expected on one machine); 1e-12 of the largest tip deflection allows
    # a different BLAS summation order over the ~3e5 sequential steps, 100x below the
    # tolerance 1e-10 the run was controlled for
    tip = np.asarray(result["tip_displacement"])
    scale = float(np.max(np.abs(whole.tip_displacement)))
    np.testing.assert_allclose(tip, whole.tip_displacement, rtol=0, atol=1e-12 * scale)
    assert diag["estimated_relative_error"] == pytest.approx(
        whole.diagnostics["estimated_relative_error"], rel=1e-6
    )
    # it resumed: the second attempt of the job continued from a checkpoint past the start
    assert diag["resumed_attempt"] == 2
    assert 0.0 < diag["resumed_from_time"] <= LONG_JOB["time"]["t_end"]
    # and did less than a restart from zero: the exponentials it carried over were not
    # computed again (the library's tests count the exponentials a resume computes:
    # exactly matrix_exponentials - resumed_exponentials)
    carried = diag["resumed_exponentials"]
    assert 0 < carried < diag["matrix_exponentials"]
    assert "resumed_from_time" not in whole.diagnostics


def _written(
    get: Callable[[str], Any], key: str, db: Path, after: float, timeout: float = 120
) -> float:
    """When the job's checkpoint was written [Unix s], once that is later than ``after``
    (the job, read by ``get(path)``, still active meanwhile)."""
    end = time.monotonic() + timeout
    while True:
        rows = [row for row in _checkpoints(db) if row[0] == key]
        if rows and rows[0][3] > after:
            return float(rows[0][3])
        job = get(f"/v1/jobs/{key}").json()
        assert job["status"] in ("queued", "running"), job
        assert time.monotonic() < end, "no checkpoint written"
        time.sleep(0.1)


#: classical RK4 on 10 modes over 15 s of the paper's example (v = 0.4 t): about 5 s of
#: fixed steps, the stability-limited step of the fastest mode
RK4_JOB: dict[str, Any] = {
    "pipe": PAPER_EXAMPLE["pipe"],
    "modes": 10,
    "method": "rk4",
    "time": {"t_end": 15.0, "samples": 101},
}


def test_an_rk4_job_resumes_after_its_worker_is_killed(tmp_path: Path) -> None:
    """The Dask worker alone is SIGKILLed (the server lives on, the nanny starts a new
    worker, Dask's worker-loss signal ends the job's lease): the second attempt resumes
    from the checkpoint at a step boundary, takes the same steps, and ends where an
    uninterrupted library run ends."""
    with make_client(
        tmp_path,
        workers=1,
        fast_lane_threads=0,
        progress_interval_s=0.1,
        stale_after_s=2.0,
        checkpoint_interval_s=1.0,
    ) as c:
        wait_ready(c)
        accepted = c.post("/v1/jobs", json=RK4_JOB)
        assert accepted.status_code == 202, accepted.text
        key = accepted.json()["key"]
        db = tmp_path / "pipeflow.sqlite3"
        _written(c.get, key, db, after=_written(c.get, key, db, after=0.0))
        record = c.app.state.store.get_job(key)  # type: ignore[attr-defined]
        pids = c.portal.call(c.app.state.runner.client.run, os.getpid)  # type: ignore[attr-defined, union-attr]
        os.kill(pids[record.worker], signal.SIGKILL)
        job = wait_app_job(c, key, timeout=180)
        assert job["status"] == "succeeded" and job["attempts"] == 2, job
        result = c.get(f"/v1/results/{key}").json()
    assert _checkpoints(db) == []

    whole = simulate(SimulationSpec.model_validate(RK4_JOB).to_simulation())
    diag = result["diagnostics"]
    assert diag["steps"] == whole.diagnostics["steps"]
    # bit-identical expected (the same steps from the same stored state); 1e-12 of the
    # largest tip deflection allows another BLAS summation order, far below RK4's own
    # error (estimated_relative_error, ~1e-6 here)
    tip = np.asarray(result["tip_displacement"])
    scale = float(np.max(np.abs(whole.tip_displacement)))
    np.testing.assert_allclose(tip, whole.tip_displacement, rtol=0, atol=1e-12 * scale)
    assert diag["resumed_attempt"] == 2
    # fewer steps than a restart from zero: those carried over were not taken again
    assert 0 < diag["resumed_steps"] < diag["steps"]
    assert 0.0 < diag["resumed_from_time"] < RK4_JOB["time"]["t_end"]
