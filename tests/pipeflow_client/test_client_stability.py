"""pipeflow_client.Client.stability / .sweep against the real app (TestClient transport)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

import pipeflow_client
from pipeflow.schema.stability import PAPER_PIPE_JSON, ArgandSweep, StabilitySpec
from pipeflow_cli.cli import main as cli_main
from pipeflow_client import Client, ServiceError

#: beta = 0.2 non-dimensional pipe (E = I = L = 1, M1 + M2 = 1): u = v sqrt(beta)
BETA_02: dict[str, Any] = {
    "pipe": {"E": 1.0, "I": 1.0, "L": 1.0, "M1": 0.8, "M2": 0.2},
    "modes": 10,
    "velocity_range": [0.0, 12.0 / math.sqrt(0.2)],
    "points": 121,
}


def test_stability_returns_the_critical_velocity(sdk_client: Client) -> None:
    """Gregory & Paidoussis (1966) / Paidoussis (1998) sec. 3.5: beta = 0.2 flutters in the
    second mode at u_cr ~ 5.6 (graphical, +-0.1); the 10-mode value is 5.5917."""
    doc = sdk_client.stability(BETA_02)
    assert doc["dimensionless"]["u_cr"] == pytest.approx(5.6, abs=0.1)
    assert doc["dimensionless"]["u_cr"] == pytest.approx(5.5917, rel=1e-4)
    assert doc["crossings"][0]["mode"] == 2 and doc["cached"] is False
    # a spec model gives the same key; the second call is served from the cache
    again = sdk_client.stability(StabilitySpec.model_validate(BETA_02))
    assert again["key"] == doc["key"] and again["cached"] is True


def test_stability_with_progress_goes_through_a_job(sdk_client: Client) -> None:
    seen: list[float] = []
    doc = sdk_client.stability({**BETA_02, "modes": 8}, progress=seen.append)
    assert seen and seen[-1] == 1.0 and all(0.0 <= f <= 1.0 for f in seen)
    assert doc["critical_velocity"] == pytest.approx(5.5917 / math.sqrt(0.2), rel=1e-3)
    assert sdk_client.job(doc["key"])["kind"] == "stability"


def test_sweep_submits_waits_and_returns_the_result(sdk_client: Client) -> None:
    spec = ArgandSweep.model_validate(
        {
            "pipe": PAPER_PIPE_JSON,
            "modes": 4,
            "tracked_modes": 2,
            "points": 21,
            "velocity_range": [0.0, 40.0],
        }
    )  # the model's "kind" is a default, not set: the client still sends it
    seen: list[float] = []
    doc = sdk_client.sweep(spec, progress=seen.append, poll=0.02, timeout=60)
    assert doc["kind"] == "argand" and len(doc["modes"]) == 2
    assert seen[-1] == 1.0
    assert doc["plots"] == ["argand", "sweep_frequency", "sweep_damping"]
    assert sdk_client.plot(doc["key"], "sweep_damping").startswith(b"\x89PNG")
    job = sdk_client.submit_sweep(spec)
    assert job["status"] == "succeeded" and job["key"] == doc["key"]


def test_sweep_errors(sdk_client: Client) -> None:
    with pytest.raises(ServiceError) as err:
        sdk_client.sweep({"kind": "bode", "pipe": PAPER_PIPE_JSON})
    assert err.value.status == 422 and err.value.field == "kind"
    with pytest.raises(ServiceError) as err:
        sdk_client.stability({**BETA_02, "velocity_range": [1.0, 0.0]})
    assert err.value.status == 422 and err.value.field == "velocity_range"
    # within every per-field bound, but over the library's work budget: refused at once
    too_big = {
        "kind": "spin_map",
        "pipe": PAPER_PIPE_JSON,
        "modes": 40,
        "velocity_range": [0.0, 1.0],
        "spin_range": [0.0, 1.0],
        "velocity_points": 200,
        "spin_points": 200,
    }
    with pytest.raises(ServiceError) as err:
        sdk_client.sweep(too_big, poll=0.02, timeout=60)
    assert err.value.status == 422 and err.value.field == "spin_points"


def test_cli_stability_with_server_draws_progress(
    service: Any,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``pipeflow stability --server URL --progress`` runs as a job and draws the bar, like
    ``pipeflow run --server``; the answer is the same critical velocity [m/s] as the
    in-process analysis (10-mode u_cr = 5.5917, rel 1e-3 as above)."""
    monkeypatch.setattr(
        pipeflow_client, "Client", lambda url, **kw: Client(url, http=service, **kw)
    )
    spec = tmp_path / "stab.json"
    spec.write_text(json.dumps({**BETA_02, "modes": 8}))
    out = tmp_path / "stab_result.json"
    argv = ["stability", str(spec), "--server", str(service.base_url), "-o", str(out)]
    assert cli_main([*argv, "--progress"]) == 0
    result = json.loads(out.read_text())
    assert result["critical_velocity"] == pytest.approx(5.5917 / math.sqrt(0.2), rel=1e-3)
    err = capsys.readouterr().err
    assert "analysing [" in err and "100.0%" in err
