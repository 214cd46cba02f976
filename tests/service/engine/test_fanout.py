"""Maps fan out over the cluster (service.engine.fanout): real Dask workers, real pieces.

The embedded LocalCluster with 2 worker processes: a spin map job's pieces run on both
workers (each piece reports the worker that ran it; the result's ``diagnostics.fan_out``
counts them), its result equals the library call's, a cancel stops the pieces not yet
started (seen in the scheduler's own task records), and an error raised inside a piece
reaches the job as a problem naming the field.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient

from pipeflow import parallel
from pipeflow.computations.registry import COMPUTATIONS
from pipeflow.schema.stability import PAPER_PIPE_JSON
from service import encoding
from service.engine.fanout import PIECE_PREFIX
from tests.service import processes
from tests.service.conftest import make_client, wait_job, wait_ready

#: the issue's map (the registry's example): the paper's pipe, 100 x 100 points, 10 modes
MAP: dict[str, Any] = COMPUTATIONS["spin_map"].examples["spin_map"]["value"]


class _Width2:
    """Stands for a cluster of 2 threads when counting the pieces the library makes."""

    width = 2

    def map(self, fn: Any, items: Any) -> Any:
        return parallel.SERIAL.map(fn, items)


def _pieces_on_two_threads() -> int:
    with parallel.hosting(_Width2()):
        return len(parallel.split(100, max_size=4096 // 100))


def _library(spec: dict[str, Any]) -> dict[str, Any]:
    """The plain library call (serial, in this process) as the service encodes it."""
    computation = COMPUTATIONS[spec["kind"]]
    result = computation.execute(computation.request.model_validate(spec))
    doc: dict[str, Any] = json.loads(encoding.dumps(result))
    return doc


@pytest.mark.slow  # a 2-worker cluster and a map, 10-20 s
def test_spin_map_job_runs_on_both_workers_and_equals_the_library_call(tmp_path: Path) -> None:
    """Over HTTP to a real uvicorn server with 2 workers: the 100 x 100 x 10-mode map's 8
    pieces ran on 2 distinct workers, and the result equals the serial library call exactly
    (tolerance 0: each line is computed on its own; only the diagnostics' fan_out entry is
    the service's own)."""
    with processes.server(
        tmp_path / "server.log", PIPEFLOW_DATA_DIR=str(tmp_path / "data"), PIPEFLOW_WORKERS="2"
    ) as (_, url):
        r = httpx.post(f"{url}/v1/sweeps", json=MAP, timeout=30)
        assert r.status_code == 202, r.text
        key = r.json()["key"]
        assert processes.wait_job(url, key)["status"] == "succeeded"
        doc = httpx.get(f"{url}/v1/results/{key}", timeout=30).json()
    assert doc.pop("key") == key and doc.pop("cached") is True  # the results endpoint's own
    fan_out = doc["diagnostics"].pop("fan_out")
    assert fan_out == {"pieces": _pieces_on_two_threads(), "workers": 2}
    assert fan_out["pieces"] == 8
    assert doc == _library(MAP)


def _piece_records(dask_scheduler: Any) -> dict[str, list[str]]:
    """Run on the scheduler: the states each piece went through (from its transition
    log) and the pieces it still holds, with their state."""
    seen: dict[str, list[str]] = {}
    for entry in dask_scheduler.transition_log:
        key, finish = str(entry[0]), str(entry[2])
        if key.startswith(PIECE_PREFIX):
            seen.setdefault(key, []).append(finish)
    held = {
        str(k): [ts.state]
        for k, ts in dask_scheduler.tasks.items()
        if str(k).startswith(PIECE_PREFIX)
    }
    return {"seen": seen, "held": held}  # type: ignore[dict-item]


@pytest.fixture(scope="module")
def two(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """The app with its embedded cluster of 2 workers, progress recorded every 20 ms."""
    with make_client(
        tmp_path_factory.mktemp("fanout"), workers=2, queue_size=4, progress_interval_s=0.02
    ) as c:
        wait_ready(c)
        yield c


def _on_scheduler(client: TestClient) -> dict[str, Any]:
    from distributed import Client

    address = client.app.state.runner._cluster.scheduler_address  # type: ignore[attr-defined]
    with Client(address, timeout="30s") as dask:
        records: dict[str, Any] = dask.run_on_scheduler(_piece_records)
    return records


def _stopped_pieces(client: TestClient, name: str) -> tuple[int, int]:
    """Once the scheduler holds no piece any more: (pieces submitted, pieces finished) of
    the one fan-out of ``name`` it saw (keys: prefix-name-token-index)."""
    _wait_released(client)
    seen = _on_scheduler(client)["seen"]
    tokens = {k.rsplit("-", 2)[1] for k in seen if k.startswith(f"{PIECE_PREFIX}-{name}-")}
    assert len(tokens) == 1, tokens
    prefix = f"{PIECE_PREFIX}-{name}-{tokens.pop()}-"
    mine = {k: v for k, v in seen.items() if k.startswith(prefix)}
    return len(mine), sum("memory" in states for states in mine.values())


#: 200 x 200 points, 20 modes: 10 pieces of about 1.5 s each on this machine
BIG = MAP | {"modes": 20, "velocity_points": 200, "spin_points": 200}


def _first_piece_in(job: dict[str, Any]) -> bool:
    return bool(job["progress"] > 0 or job["status"] not in ("queued", "running"))


def test_cancelling_a_fanned_out_job_stops_its_pieces(two: TestClient) -> None:
    """The big map cancelled once its first piece is in: the job ends cancelled, the
    scheduler soon holds none of its pieces, and fewer pieces finished than were submitted
    (the queued ones never ran; the running ones finish their chunk)."""
    key = two.post("/v1/sweeps", json=BIG).json()["key"]
    wait_job(two, key, until=_first_piece_in)
    assert two.delete(f"/v1/jobs/{key}").status_code == 200
    assert wait_job(two, key)["status"] == "cancelled"
    submitted, finished = _stopped_pieces(two, "_spin_lines")
    assert submitted == 10
    assert 1 <= finished < submitted


def _job_worker(prefix: str, dask_scheduler: Any = None) -> dict[str, Any]:
    """Run on the scheduler: the worker computing the task whose key starts with
    ``prefix`` (the job's own task), and every worker."""
    on = [
        ts.processing_on.address
        for k, ts in dask_scheduler.tasks.items()
        if str(k).startswith(prefix) and ts.processing_on is not None
    ]
    return {"job": on, "workers": sorted(dask_scheduler.workers)}


@pytest.mark.slow  # a killed worker / a runtime limit, 10-15 s
def test_a_piece_whose_worker_dies_is_rerun(two: TestClient) -> None:
    """SIGKILL of the worker that does not hold the job's task, while the big map's pieces
    run: the scheduler reruns its pieces elsewhere, the job succeeds in its first attempt,
    and its lines equal the library's pieces computed here (tolerance 0)."""
    import os
    import signal

    import numpy as np
    from distributed import Client

    from pipeflow.stability import maps

    spec = BIG | {"spin_range": [0.0, 1999.0]}  # a key of its own
    key = two.post("/v1/sweeps", json=spec).json()["key"]
    wait_job(two, key, until=_first_piece_in)
    address = two.app.state.runner._cluster.scheduler_address  # type: ignore[attr-defined]
    with Client(address, timeout="30s") as dask:
        where = dask.run_on_scheduler(_job_worker, f"spin_map-{key}")
        assert len(where["job"]) == 1, where
        other = next(w for w in where["workers"] if w != where["job"][0])
        pid = dask.run(os.getpid, workers=[other])[other]
        os.kill(pid, signal.SIGKILL)
    job = wait_job(two, key, timeout=120)
    assert job["status"] == "succeeded" and job["attempts"] == 1, job
    doc = two.get(f"/v1/results/{key}").json()
    assert doc["diagnostics"]["fan_out"]["pieces"] == 10
    request = COMPUTATIONS["spin_map"].request.model_validate(spec)
    v = np.linspace(0.0, 60.0, 200)
    rows = [0, 101, 199]
    w = np.linspace(0.0, 1999.0, 200)[rows]
    growth, _, stable, how = maps._spin_lines(
        maps._SpinLines(request.mounted_pipe(), 20, v, w, 1e-10)
    )
    for i, row in enumerate(rows):
        assert doc["growth_rate"][row] == growth[i].tolist()
        assert doc["stable_at_start"][row] == stable[i]
        assert doc["instability_at_start"][row] == how[i]


@pytest.mark.slow  # a killed worker / a runtime limit, 10-15 s
def test_runtime_limit_stops_a_fanned_out_job(tmp_path: Path) -> None:
    """With a 2 s runtime limit the big map (about 8 s on 2 workers) fails with the
    runtime-limit problem, checked between pieces, and its remaining pieces are cancelled."""
    with make_client(
        tmp_path, workers=2, queue_size=2, job_timeout_s=2.0, progress_interval_s=0.02
    ) as c:
        wait_ready(c)
        key = c.post("/v1/sweeps", json=BIG).json()["key"]
        job = wait_job(c, key, timeout=60)
        assert job["status"] == "failed", job
        assert job["error"]["type"].endswith("/runtime-limit"), job["error"]
        submitted, finished = _stopped_pieces(c, "_spin_lines")
        assert submitted == 10 and finished < submitted


def test_an_error_inside_a_piece_reaches_the_job_with_its_field(two: TestClient) -> None:
    """A resonance chart whose monodromy matrices cannot reach tolerance 1e-12 with 6 modes
    within the step budget: the BudgetExceeded is raised by the step doubling inside a piece
    on a worker process, and the job fails with the library's 422 problem naming the
    request field ``tolerance``, as it does in-process."""
    spec = {
        "kind": "resonance_chart",
        "pipe": PAPER_PIPE_JSON,
        "modes": 6,
        "mean_velocity": 10.0,
        "amplitude_range": [0.0, 8.0],
        "frequency_range": [100.0, 4000.0],
        "amplitude_points": 3,
        "frequency_points": 4,
        "tolerance": 1e-12,
    }
    key = two.post("/v1/sweeps", json=spec).json()["key"]
    job = wait_job(two, key, timeout=120)
    assert job["status"] == "failed", job
    error = job["error"]
    assert error["status"] == 422 and error["type"].endswith("/budget-exceeded")
    assert error["errors"][0]["field"] == "tolerance"
    assert "did not converge to 1e-12" in error["detail"]
    assert not _on_scheduler(two)["held"] or _wait_released(two)


def _wait_released(client: TestClient) -> bool:
    end = time.monotonic() + 30
    while _on_scheduler(client)["held"]:
        assert time.monotonic() < end, "the failed chart's pieces are still held"
        time.sleep(0.2)
    return True


def test_a_study_fans_its_cases_out_through_the_same_host(two: TestClient) -> None:
    """A 64-case grid study (tiny simulations): its chunks of cases ran as Dask pieces (8 on
    a cluster of 2 threads, all finished), each validating, keying, computing and memoising
    its own cases on its worker; the table is the serial library call's (keys, statuses and
    counts exactly; numbers to 1e-12 relative: other processes, whose BLAS may round
    differently), and an overlapping study is served by the memo the pieces wrote."""
    from pipeflow.schema.study import StudySpec
    from tests.pipeflow.cases import TINY

    def grid(values: list[float]) -> dict[str, Any]:
        return {"base": TINY["study"]["base"], "grid": {"pipe.E": values}}

    values = [7e9 + i * 1e7 for i in range(64)]
    r = two.post("/v1/studies", json=grid(values))
    assert r.status_code == 202, r.text
    key = r.json()["key"]
    assert wait_job(two, key, timeout=120)["status"] == "succeeded"
    submitted, finished = _stopped_pieces(two, "run_piece")
    assert submitted == finished == 8
    doc = two.get(f"/v1/results/{key}").json()
    assert len(doc["rows"]) == 64
    want = COMPUTATIONS["study"].execute(StudySpec.model_validate(grid(values)))
    assert doc["counts"] == want["counts"] == {
        "total": 64, "ok": 64, "failed": 0, "cached": 0, "computed": 64
    }  # fmt: skip
    for got, row in zip(doc["rows"], want["rows"], strict=True):
        for a, b in zip(got, row, strict=True):
            if isinstance(b, float):
                assert a == pytest.approx(b, rel=1e-12, abs=0.0)
            else:
                assert a == b
    # half of it again, with 8 new cases: the memo rows the pieces wrote serve the rest
    r = two.post("/v1/studies", json=grid(values[32:] + [6e9 + i * 1e7 for i in range(8)]))
    key = r.json()["key"]
    assert wait_job(two, key, timeout=120)["status"] == "succeeded"
    again = two.get(f"/v1/results/{key}").json()
    assert again["counts"] == {"total": 40, "ok": 40, "failed": 0, "cached": 32, "computed": 8}
    assert [row[3] for row in again["rows"]] == [True] * 32 + [False] * 8
    assert [row[1] for row in again["rows"][:32]] == [row[1] for row in doc["rows"][32:]]
