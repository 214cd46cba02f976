"""POST /v1/state-space (issue 32): the library's realisation through the real app, its
transfer function equal to the frequency-response endpoint's answer, a MATLAB file read
back by scipy, python-control driving the answer, the clients, and refusals naming the
field.
"""

from __future__ import annotations

import asyncio
import copy
import io
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
import scipy.io
from fastapi.testclient import TestClient

from pipeflow.schema.frequency import HAMMER_EXAMPLE
from pipeflow.schema.state_space import STATE_SPACE_EXAMPLE
from pipeflow_cli.cli import main as cli_main
from pipeflow_client import AsyncClient, Client
from tests.service.conftest import make_client, wait_ready

L = HAMMER_EXAMPLE["pipe"]["L"]


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with make_client(tmp_path_factory.mktemp("ss"), workers=1, queue_size=8) as c:
        wait_ready(c)
        yield c


def test_transfer_function_equals_the_frf_endpoint(api: TestClient) -> None:
    """C (iW - A)^-1 B + D of the answer vs POST /v1/frequency-responses at the same body
    with residual_flexibility false, at explicit frequencies: 1e-10 of the curve's max
    (same modal model, a dense solve here vs the eigen-decomposition there); eig(A) vs the
    FRF's peaks (damped frequencies Im xi, 1e-9)."""
    body = copy.deepcopy(STATE_SPACE_EXAMPLE)
    body["response"] = {"positions": [0.5 * L, L], "quantity": "velocity"}
    r = api.post("/v1/state-space", json=body)
    assert r.status_code == 200, r.text
    doc = r.json()
    assert doc["kind"] == "state_space" and doc["units"]["outputs"] == "m/s"
    A, B, C, D = (np.asarray(doc[k]) for k in ("A", "B", "C", "D"))
    n2 = A.shape[0]
    assert n2 == 2 * body["modes"] and len(doc["states"]) == n2 and len(doc["outputs"]) == 2
    W = list(np.geomspace(10.0, 8000.0, 50))
    frf_body = {**body, "frequencies": {"values": W}, "residual_flexibility": False}
    frf = api.post("/v1/frequency-responses", json=frf_body).json()
    (point,) = frf["operating_points"]
    H = np.array([np.asarray(c["real"]) + 1j * np.asarray(c["imag"]) for c in point["responses"]])
    G = np.stack([(C @ np.linalg.solve(1j * w * np.eye(n2) - A, B) + D)[:, 0] for w in W], axis=1)
    assert np.max(np.abs(G - H)) <= 1e-10 * np.max(np.abs(H))
    lam = np.linalg.eigvals(A)
    for peak in point["peaks"]:
        assert np.min(np.abs(lam.imag - peak["frequency"])) <= 1e-9 * peak["frequency"]
    again = api.post("/v1/state-space", json=body)
    assert again.headers["x-cache"] == "HIT" and again.json()["key"] == doc["key"]


def test_mat_file_control_and_clients(api: TestClient, tmp_path: Path) -> None:
    """?format=mat read back by scipy.io.loadmat equals the JSON (doubles: exactly); the
    matrices drive python-control (its frequency response at 100 rad/s equals C (iW-A)^-1 B);
    Client and AsyncClient give the same answer and file."""
    control = pytest.importorskip("control")
    doc = api.post("/v1/state-space", json=STATE_SPACE_EXAMPLE).json()
    r = api.get(f"/v1/results/{doc['key']}", params={"format": "mat"})
    assert r.status_code == 200 and r.headers["content-type"] == "application/x-matlab-data"
    m = scipy.io.loadmat(io.BytesIO(r.content))
    for k in ("A", "B", "C", "D"):
        np.testing.assert_array_equal(m[k], np.asarray(doc[k]))
    assert [str(s[0]) for s in m["states"].ravel()] == doc["states"]
    sys = control.ss(m["A"], m["B"], m["C"], m["D"])
    h = np.asarray(control.frequency_response(sys, [100.0]).complex).reshape(-1)[0]
    A, B, C = (np.asarray(doc[k]) for k in ("A", "B", "C"))
    ref = (C @ np.linalg.solve(100j * np.eye(A.shape[0]) - A, B))[0, 0]
    assert abs(h - ref) <= 1e-12 * abs(ref)
    with Client(str(api.base_url), http=api) as client:
        assert client.state_space(STATE_SPACE_EXAMPLE)["A"] == doc["A"]
        assert client.result_file(doc["key"], "mat") == r.content

    async def scenario() -> dict[str, Any]:
        transport = httpx.ASGITransport(app=api.app)  # type: ignore[arg-type]
        async with httpx.AsyncClient(transport=transport, base_url="http://test") as http:
            async with AsyncClient("http://test", http=http) as client:
                out: dict[str, Any] = await client.state_space(STATE_SPACE_EXAMPLE)
                return out

    assert asyncio.run(scenario())["key"] == doc["key"]
    spec = tmp_path / "ss.json"
    spec.write_text(json.dumps(STATE_SPACE_EXAMPLE))
    out = tmp_path / "ss.mat"  # the command line computes locally: the same matrices
    argv = ["run", str(spec), "--kind", "state_space", "--format", "mat", "-o", str(out)]
    assert cli_main([*argv, "--quiet"]) == 0
    np.testing.assert_array_equal(scipy.io.loadmat(out)["A"], np.asarray(doc["A"]))
    frf = api.post("/v1/frequency-responses", json=HAMMER_EXAMPLE).json()
    bad = api.get(f"/v1/results/{frf['key']}", params={"format": "mat"})
    assert bad.status_code == 422 and bad.json()["errors"][0]["field"] == "format"


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"response": {"positions": [1.0]}}, "response.positions"),
        ({"modes": 41}, "modes"),
        ({"flow": {"velocity": {"kind": "linear", "coefficients": [0, 1]}}}, "flow.velocity"),
        ({"frequencies": {"values": [1.0]}}, "frequencies"),
    ],
)
def test_refusals_name_the_field(api: TestClient, change: dict[str, Any], field: str) -> None:
    body = {**copy.deepcopy(STATE_SPACE_EXAMPLE), **change}
    r = api.post("/v1/state-space", json=body)
    assert r.status_code == 422, r.text
    assert r.headers["content-type"] == "application/problem+json"
    assert field in [e["field"] for e in r.json()["errors"]]
