"""pipeflow_client.Client against the real app (FastAPI TestClient as the httpx transport)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

import pipeflow_client
from pipeflow.schema.results import SimulationResponse, StabilityResponse
from pipeflow_cli.cli import main as cli_main
from pipeflow_client import Client, JobFailed, ServiceError, SimulationResult
from tests.service.conftest import SMALL


def test_simulate_returns_numpy_arrays(sdk_client: Client) -> None:
    r = sdk_client.simulate(SMALL)
    assert isinstance(r, SimulationResult)
    assert len(r.key) == 64 and r.status == "ok"
    assert r.t.shape == r.tip_displacement.shape == (101,)
    assert r.t[-1] == pytest.approx(0.2)
    assert r.tip_displacement[0] == pytest.approx(2.7244e-3, rel=1e-3)  # [m]
    assert r.sigma.shape == r.omega.shape == (r.eigen_t.size, 3)
    assert np.all(r.omega[:, 0] > 0)  # [rad/s]
    assert r.plots[:3] == ["tip_displacement", "damping", "frequency"]
    again = sdk_client.simulate(SMALL)
    assert again.cached and again.key == r.key
    np.testing.assert_array_equal(again.tip_displacement, r.tip_displacement)
    # the views come from the document validated with the service's own response model
    assert isinstance(r.model, SimulationResponse) and r.model.key == r.key
    assert r.model.model_dump(exclude_unset=True) == r.raw


def test_job_with_progress_then_fetch_by_key(sdk_client: Client) -> None:
    spec = dict(SMALL, time={"t_end": 0.3, "samples": 61})
    seen: list[float] = []
    job = sdk_client.submit(spec)
    assert job["status"] in ("queued", "running", "succeeded")
    r = sdk_client.wait(job["key"], progress=seen.append, poll=0.02, timeout=60)
    assert seen and seen[-1] == 1.0 and all(0 <= f <= 1 for f in seen)
    assert r.t.size == 61
    stored = sdk_client.result(r.key)
    np.testing.assert_array_equal(stored.tip_displacement, r.tip_displacement)
    # simulate with a progress callback goes through the same job path
    assert sdk_client.simulate(spec, progress=lambda f: None).key == r.key


def test_csv_and_plots_through_the_client(sdk_client: Client) -> None:
    key = sdk_client.simulate(SMALL).key
    text = sdk_client.result_csv(key, "eigenvalues")
    assert text.splitlines()[0].startswith("t [s],sigma_1 [1/s],omega_1 [rad/s]")
    assert sdk_client.plot(key, "damping", "png").startswith(b"\x89PNG")
    assert b"<svg" in sdk_client.plot(key, "frequency", "svg")


def test_service_errors_carry_problem_details(sdk_client: Client) -> None:
    bad = json.loads(json.dumps(SMALL))
    bad["pipe"]["E"] = -1.0
    with pytest.raises(ServiceError) as err:
        sdk_client.simulate(bad)
    assert err.value.status == 422
    assert err.value.field == "pipe.E"
    assert err.value.problem["status"] == 422
    assert "pipe.E" in str(err.value)

    with pytest.raises(ServiceError) as err:
        sdk_client.result("0" * 64)
    assert err.value.status == 404 and "no result" in err.value.problem["detail"]

    with pytest.raises(ServiceError) as err:
        sdk_client.plot(sdk_client.simulate(SMALL).key, "bode")
    assert err.value.status == 404 and err.value.field == "name"


def test_failed_job_raises_job_failed(sdk_client: Client) -> None:
    # an explicit RK4 step far outside the stability region is refused by the solver
    spec = dict(SMALL, method="rk4", options={"step": 0.01})
    job = sdk_client.submit(spec)
    with pytest.raises(JobFailed) as err:
        sdk_client.wait(job["key"], poll=0.02, timeout=60)
    assert err.value.field == "options.step"


def test_cli_run_and_plot_with_server(
    service: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the CLI builds Client(url); route it through the in-process app
    monkeypatch.setattr(
        pipeflow_client, "Client", lambda url, **kw: Client(url, http=service, **kw)
    )
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps(SMALL))
    out = tmp_path / "r.json"
    url = str(service.base_url)
    assert cli_main(["run", str(spec), "--server", url, "-o", str(out), "--progress"]) == 0
    result = json.loads(out.read_text())
    assert len(result["key"]) == 64 and len(result["t"]) == 101
    png = tmp_path / "tip.png"
    assert cli_main(["plot", str(spec), "--server", url, "--out", str(png), "--quiet"]) == 0
    assert png.read_bytes().startswith(b"\x89PNG")


def test_compare_through_the_client(sdk_client: Client) -> None:
    """Client.compare against the real app: magnus is the baseline on a time-variant case."""
    doc = sdk_client.compare(SMALL, ["cma", "magnus"])
    assert doc["baseline"] == "magnus"
    assert [r["method"] for r in doc["methods"]] == ["cma", "magnus"]
    with pytest.raises(ServiceError) as err:
        sdk_client.compare(SMALL, ["nope"])
    assert err.value.status == 422 and (err.value.field or "").startswith("methods")


def test_results_are_validated_with_the_services_response_models(sdk_client: Client) -> None:
    """A document off the contract fails in the client, naming the field."""
    doc = sdk_client.simulate_raw(SMALL)
    broken = {k: v for k, v in doc.items() if k != "fundamental"}
    with pytest.raises(ValidationError, match="fundamental"):
        SimulationResult.from_json(broken)
    stability = sdk_client.stability(
        {"pipe": SMALL["pipe"], "modes": 3, "velocity_range": [0.0, 40.0], "points": 11}
    )
    assert isinstance(pipeflow_client.parse("stability", stability), StabilityResponse)
    with pytest.raises(ValidationError, match="crossings"):
        pipeflow_client.parse("stability", {**stability, "crossings": [{"velocity": 1.0}]})


def test_an_impulse_through_the_client(sdk_client: Client) -> None:
    """A hammer blow (issue 32) through the client and the real app: no response before the
    blow (u0 = 0), a response after it, the load echoed; a bad station names its field."""
    body = {
        **SMALL,
        "flow": {"velocity": {"kind": "constant", "value": 0.0}},
        "initial": {"u0": 0.0},
        "loads": [{"kind": "impulse", "position": 0.025, "impulse": 1e-9, "time": 0.05}],
    }
    r = sdk_client.simulate(body)
    assert r.status == "ok"
    before = r.t < 0.05
    assert np.all(r.tip_displacement[before] == 0.0)
    assert np.max(np.abs(r.tip_displacement[~before])) > 0
    assert r.raw["loads"] == body["loads"]
    bad = {**body, "loads": [{**body["loads"][0], "position": 0.03}]}
    with pytest.raises(ServiceError) as info:
        sdk_client.simulate(bad)
    assert "loads.0.position" in str(info.value)


def test_the_clients_job_states_are_the_services() -> None:
    """The client names the job states it acts on (no bare strings); they are the service's
    (service.engine.lifecycle.JobState), value for value."""
    from pipeflow_client.client import JobStatus
    from service.engine.lifecycle import JobState

    assert [s.value for s in JobStatus] == [s.value for s in JobState]
