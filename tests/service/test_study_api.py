"""POST /v1/studies: design studies as jobs on the real engine (embedded Dask cluster).

The cases run on the job's worker (serially until the service installs a Dask host for
``pipeflow.parallel``); each case's summary is kept in the store as a row of kind
``study_case``, so the number of those rows counts the case computations independently of
the study's own ``counts``.  Numbers are checked against the standalone requests of the
same cases, sent to the same service (the identity the per-case keys promise).
"""

from __future__ import annotations

import csv
import io
import time
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from pipeflow.schema.results import StudyResponse
from pipeflow.schema.study import MAX_CASES
from service.store.tables import results
from tests.service.conftest import SMALL, make_client, wait_job, wait_ready

#: the service tests' small simulation with an explicit-step method (max_steps applies)
BASE: dict[str, Any] = {**SMALL, "method": "rk4"}


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """One worker, progress written every 0.05 s."""
    with make_client(tmp_path_factory.mktemp("studies"), progress_interval_s=0.05) as c:
        wait_ready(c)
        yield c


def case_rows(api: TestClient) -> int:
    """Per-case summaries in the store (one per case computation)."""
    store = api.app.state.store  # type: ignore[attr-defined]
    with store.engine.connect() as conn:
        query = select(func.count()).where(results.c.kind == "study_case")
        return int(conn.execute(query).scalar_one())


def submit(api: TestClient, body: dict[str, Any]) -> dict[str, Any]:
    r = api.post("/v1/studies", json=body)
    assert r.status_code == 202, r.text
    job = r.json()
    assert r.headers["Location"] == f"/v1/jobs/{job['key']}" and job["kind"] == "study"
    return job


def run(api: TestClient, body: dict[str, Any]) -> dict[str, Any]:
    job = wait_job(api, submit(api, body)["key"], timeout=240)
    assert job["status"] == "succeeded" and job["progress"] == 1.0, job
    result = api.get(f"/v1/results/{job['key']}")
    assert result.status_code == 200
    doc: dict[str, Any] = result.json()
    return doc


def named(doc: dict[str, Any]) -> list[dict[str, Any]]:
    names = [c["name"] for c in doc["columns"]]
    return [dict(zip(names, row, strict=True)) for row in doc["rows"]]


def test_a_study_job_gives_a_table_of_the_standalone_results_and_its_csv(
    api: TestClient,
) -> None:
    body = {
        "base": {"kind": "simulation", "spec": BASE},
        "cases": [{"pipe.E": 7.0e9}, {"options.max_steps": 1}, {"pipe.E": 8.0e9}],
    }
    doc = run(api, body)
    assert doc["kind"] == "study" and doc["base_kind"] == "simulation"
    StudyResponse.model_validate(doc)  # exactly the documented fields, both ways
    assert set(doc) == set(StudyResponse.model_fields)
    assert doc["counts"] == {"total": 3, "ok": 2, "failed": 1, "cached": 0, "computed": 3}
    rows = named(doc)
    # a failing case is a row, not a failed study
    assert rows[1]["status"] == "failed" and rows[1]["error_field"] == "options.max_steps"
    assert rows[1]["error_type"] == "budget-exceeded"
    for row, E in ((rows[0], 7.0e9), (rows[2], 8.0e9)):
        alone = api.post("/v1/simulations", json={**BASE, "pipe": {**BASE["pipe"], "E": E}})
        assert alone.status_code == 200
        # the case's key is the standalone request's, and the study kept only a summary
        # under its own name: the standalone request was computed (MISS), not served it
        assert alone.json()["key"] == row["key"] and alone.headers["X-Cache"] == "MISS"
        full = alone.json()
        # same computation on another worker process, one BLAS thread each: equal but for
        # the last bits at most
        assert row["peak_tip_displacement"] == pytest.approx(
            max(abs(u) for u in full["tip_displacement"]), rel=1e-12
        )
        assert row["final_sigma_1"] == pytest.approx(full["fundamental"]["sigma"][-1], rel=1e-12)
        assert row["final_omega_1"] == pytest.approx(full["fundamental"]["omega"][-1], rel=1e-12)
    # CSV export of the stored result: its one table, units in the header
    r = api.get(f"/v1/results/{doc['key']}", params={"format": "csv"})
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    table = list(csv.reader(io.StringIO(r.text)))
    assert table[0][:5] == ["index [-]", "key", "status", "cached", "pipe.E [Pa]"]
    assert "options.max_steps [-]" in table[0] and "final_omega_1 [rad/s]" in table[0]
    assert [t[2] for t in table[1:]] == ["ok", "failed", "ok"]
    peak = table[0].index("peak_tip_displacement [m]")
    assert float(table[1][peak]) == rows[0]["peak_tip_displacement"]  # round-trip digits
    assert table[2][peak] == ""
    assert api.get(f"/v1/results/{doc['key']}", params={"table": "history"}).status_code == 200
    r = api.get(f"/v1/results/{doc['key']}", params={"format": "csv", "table": "history"})
    assert r.status_code == 404 and "this result has: study" in r.json()["detail"]


def test_overlapping_studies_compute_only_their_new_cases(api: TestClient) -> None:
    def grid(*E: float) -> dict[str, Any]:
        return {"base": {"kind": "simulation", "spec": BASE}, "grid": {"pipe.E": list(E)}}

    before = case_rows(api)
    first = run(api, grid(7.1e9, 7.2e9, 7.3e9))
    assert first["counts"]["cached"] == 0 and first["counts"]["computed"] == 3
    assert case_rows(api) == before + 3
    second = run(api, grid(7.2e9, 7.3e9, 7.4e9))
    assert second["counts"] == {"total": 3, "ok": 3, "failed": 0, "cached": 2, "computed": 1}
    assert case_rows(api) == before + 4  # one more case computation, not three
    rows1, rows2 = named(first), named(second)
    assert [r["cached"] for r in rows2] == [True, True, False]
    for a, b in ((rows1[1], rows2[0]), (rows1[2], rows2[1])):
        assert {k: v for k, v in a.items() if k not in ("index", "cached")} == {
            k: v for k, v in b.items() if k not in ("index", "cached")
        }


def test_progress_counts_the_cases_done(api: TestClient) -> None:
    n = 48  # three chunks of 16 cases, about a second each
    body = {
        "base": {"kind": "simulation", "spec": BASE},
        "grid": {"pipe.E": [6.0e9 + 1e7 * i for i in range(n)]},
    }
    key = submit(api, body)["key"]
    seen = set()
    end = time.monotonic() + 240
    while True:
        job = api.get(f"/v1/jobs/{key}").json()
        seen.add(job["progress"])
        if job["status"] in ("succeeded", "failed", "cancelled"):
            break
        assert time.monotonic() < end, job
        time.sleep(0.02)
    assert job["status"] == "succeeded"
    # every value seen is a whole number of chunks' cases over the total, exactly
    assert seen <= {0.0, 16 / n, 32 / n, 1.0}, seen
    assert seen & {16 / n, 32 / n}, f"no progress seen between the chunks: {seen}"


def problem_fields(api: TestClient, body: dict[str, Any]) -> list[tuple[str, str]]:
    r = api.post("/v1/studies", json=body)
    assert r.status_code == 422, r.text
    assert r.headers["content-type"] == "application/problem+json"
    return [(e["field"], e["pointer"]) for e in r.json()["errors"]]


def test_bad_studies_are_refused_naming_the_field_before_any_work(api: TestClient) -> None:
    jobs = api.app.state.store.job_counts()  # type: ignore[attr-defined]
    base = {"kind": "simulation", "spec": BASE}
    too_many = {"base": base, "cases": [{"pipe.E": 7e9}] * (MAX_CASES + 1)}
    assert problem_fields(api, too_many) == [("cases", "#/cases")]
    grid = {"base": base, "grid": {"pipe.E": [7e9] * 101, "pipe.L": [0.025] * 100}}
    assert problem_fields(api, grid) == [("grid", "#/grid")]
    bad_value = {"base": base, "cases": [{}, {"pipe.E": -1.0}]}
    assert problem_fields(api, bad_value) == [("cases.1.pipe.E", "#/cases/1/pipe.E")]
    bad_grid_value = {"base": base, "grid": {"pipe.L": [0.02, 0.0]}}
    assert problem_fields(api, bad_grid_value) == [("grid.pipe.L.1", "#/grid/pipe.L/1")]
    no_field = {"base": base, "cases": [{"pipe.X": 1.0}]}
    assert problem_fields(api, no_field) == [("cases.0.pipe.X", "#/cases/0/pipe.X")]
    text = {"base": base, "cases": [{"pipe.E": "7e9"}]}
    assert problem_fields(api, text) == [("cases.0.pipe.E", "#/cases/0/pipe.E")]
    assert api.app.state.store.job_counts() == jobs  # type: ignore[attr-defined]


def test_the_client_runs_a_study_and_reads_its_csv(api: TestClient) -> None:
    from pipeflow_client import Client

    body = {
        "base": {
            "kind": "stability",
            "spec": {
                "pipe": BASE["pipe"],
                "modes": 4,
                "velocity_range": [0.0, 60.0],
                "points": 101,
            },
        },
        "grid": {"rotation.omega0.value": [0.0, 100.0]},
    }
    seen: list[float] = []
    with Client(str(api.base_url), http=api) as client:
        doc = client.study(body, progress=seen.append, poll=0.05, timeout=240)
        text = client.result_csv(doc["key"], table="study")
    rows = named(doc)
    assert [r["rotation.omega0.value"] for r in rows] == [0.0, 100.0]
    alone = api.post(
        "/v1/stability",
        json={**body["base"]["spec"], "rotation": {"omega0": {"kind": "constant", "value": 100.0}}},
    ).json()
    assert rows[1]["key"] == alone["key"]
    assert rows[1]["critical_velocity"] == pytest.approx(alone["critical_velocity"], rel=1e-12)
    header = next(csv.reader(io.StringIO(text)))
    assert "critical_velocity [m/s]" in header and "rotation.omega0.value [rad/s]" in header


def _close(a: Any, b: Any, rel: float = 1e-12) -> bool:
    """Equal JSON trees, numbers to ``rel`` (relative; absolute below 1e-300)."""
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_close(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return isinstance(b, list) and len(a) == len(b) and all(map(_close, a, b))
    if isinstance(a, float) and isinstance(b, int | float) and not isinstance(b, bool):
        return abs(a - b) <= rel * max(abs(a), abs(b), 1e-300)
    return bool(a == b)


def test_a_sampled_study_gives_the_librarys_statistics_and_sensitivity(api: TestClient) -> None:
    from pipeflow.computations import registry

    body = {
        "base": {"kind": "simulation", "spec": {**BASE, "time": {"t_end": 0.02, "samples": 5}}},
        "samples": {
            "count": 4,
            "method": "saltelli",
            "seed": 5,
            "parameters": {
                "pipe.E": {"distribution": "lognormal", "median": 7.8e9, "sigma": 0.1},
                "pipe.M2": {
                    "distribution": "truncated_normal",
                    "mean": 1.6485e-5,
                    "std": 2e-6,
                    "low": 1e-5,
                    "high": 2e-5,
                },
            },
        },
    }
    doc = run(api, body)
    StudyResponse.model_validate(doc)
    assert doc["counts"]["total"] == 4 * 6 and doc["overrides"] == ["pipe.E", "pipe.M2"]
    local = registry.COMPUTATIONS["study"].execute(registry.parse("study", body))
    assert _close(doc["statistics"], local["statistics"]), (doc["statistics"], local)
    assert _close(doc["sensitivity"], local["sensitivity"])
    assert doc["sensitivity"]["columns"]["final_omega_1"]["available"]
    assert _close(doc["rows"], local["rows"])
    # the same body is the same study: the job's key
    again = submit(api, body)
    assert again["key"] == doc["key"]


def test_bad_samples_are_refused_naming_the_field(api: TestClient) -> None:
    base = {"kind": "simulation", "spec": BASE}
    lognormal = {"distribution": "lognormal", "median": 7.8e9, "sigma": 0.1}

    def samples(**parameters: Any) -> dict[str, Any]:
        return {"base": base, "samples": {"count": 4, "parameters": parameters}}

    sigma = samples(**{"pipe.E": {**lognormal, "sigma": 0.0}})
    assert problem_fields(api, sigma) == [
        ("samples.parameters.pipe.E.sigma", "#/samples/parameters/pipe.E/sigma")
    ]
    text = samples(**{"pipe.E": {**lognormal, "sigma": "0.1"}})  # below the union's tag
    assert problem_fields(api, text) == [
        ("samples.parameters.pipe.E.sigma", "#/samples/parameters/pipe.E/sigma")
    ]
    unknown = samples(**{"pipe.E": {"distribution": "weibull"}})
    assert problem_fields(api, unknown) == [
        ("samples.parameters.pipe.E", "#/samples/parameters/pipe.E")
    ]
    uniform = samples(**{"pipe.L": {"distribution": "uniform", "low": 0.03, "high": 0.02}})
    assert problem_fields(api, uniform) == [
        ("samples.parameters.pipe.L.low", "#/samples/parameters/pipe.L/low")
    ]
    obj = samples(pipe={"distribution": "uniform", "low": 1.0, "high": 2.0})
    assert problem_fields(api, obj) == [("samples.parameters.pipe", "#/samples/parameters/pipe")]
    both = {**samples(**{"pipe.E": lognormal}), "grid": {"pipe.L": [0.02]}}
    assert problem_fields(api, both) == [("samples", "#/samples")]
    many = samples(**{p: lognormal for p in ("pipe.E", "pipe.L", "pipe.M2")})
    many["samples"].update(count=2000, method="saltelli")
    r = api.post("/v1/studies", json=many)
    assert r.status_code == 422 and r.json()["errors"][0]["field"] == "samples.count"
    assert "count is at most 1250" in r.json()["errors"][0]["message"]
