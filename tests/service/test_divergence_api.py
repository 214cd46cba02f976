"""A diverged run over HTTP (issue 24): its eigenvalue traces stop where its history does
(the real app: Dask workers and its store)."""

from __future__ import annotations

import copy
from typing import Any

from fastapi.testclient import TestClient

from pipeflow.schema.simulation import PAPER_EXAMPLE


def test_a_diverged_runs_traces_end_at_the_divergence_time(client: TestClient) -> None:
    """v = 20 + 1000 t m/s passes v_cr = 27.69 m/s at 7.7 ms; the tip passes 0.1 L at
    21.2 ms of the 50 ms asked.  The traces (frozen and CMA exponents) end there, with
    their samples evenly spread from 0; before, they ran to 50 ms."""
    body: dict[str, Any] = copy.deepcopy(PAPER_EXAMPLE)
    body["flow"] = {"velocity": {"kind": "polynomial", "coefficients": [20.0, 1000.0]}}
    body["initial"] = {"u0": 1e-6}
    body["time"] = {"t_end": 0.05, "samples": 501}
    body["output"] = {"eigen_samples": 101}
    r = client.post("/v1/simulations", json=body)
    assert r.status_code == 200, r.text
    doc = r.json()
    assert doc["status"] == "diverged"
    stop = doc["divergence_time"]
    assert 0.01 < stop < 0.05 and doc["t"][-1] == stop
    for block in ("eigenvalues", "cma_exponents"):
        t = doc[block]["t"]
        assert t[0] == 0.0 and t[-1] == stop and len(t) == 101, block
        assert all(len(m["sigma"]) == len(t) for m in doc[block]["modes"])
    got = client.get(f"/v1/results/{doc['key']}")  # the stored document, read back
    assert got.status_code == 200
    assert got.json()["eigenvalues"]["t"] == doc["eigenvalues"]["t"]
