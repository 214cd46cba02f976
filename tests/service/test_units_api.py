"""Quantities with their unit over HTTP (issue 24): one key for one physics, and a wrong
dimension is a 422 problem naming the field (the real app: Dask workers and its store)."""

from __future__ import annotations

import copy
import math
from typing import Any

from fastapi.testclient import TestClient

from pipeflow.schema.simulation import PAPER_EXAMPLE


def _body(omega0: Any) -> dict[str, Any]:
    body = copy.deepcopy(PAPER_EXAMPLE)
    body["rotation"]["omega0"] = {"kind": "constant", "value": omega0}
    body["time"] = {"t_end": 0.05, "samples": 51}
    body["modes"] = 3
    return body


def test_rpm_and_rad_per_s_are_one_result(client: TestClient) -> None:
    a = client.post("/v1/simulations", json=_body({"value": 3000, "unit": "rpm"}))
    assert a.status_code == 200, a.text
    b = client.post("/v1/simulations", json=_body(100 * math.pi))
    assert b.status_code == 200, b.text
    assert a.json()["key"] == b.json()["key"]
    assert b.json()["cached"] is True  # the second request is the first one's result


def test_a_wrong_dimension_is_a_422_naming_the_field(client: TestClient) -> None:
    r = client.post("/v1/simulations", json=_body({"value": 3000, "unit": "mm"}))
    assert r.status_code == 422, r.text
    assert r.headers["content-type"] == "application/problem+json"
    (error,) = r.json()["errors"]
    assert error["field"] == "rotation.omega0.value"
    assert "is a length, not an angular velocity or rate [rad/s]" in error["message"]
    bogus = _body(0.0)
    bogus["pipe"]["L"] = {"value": 25, "unit": "parsecs per fortnight^2"}
    r = client.post("/v1/simulations", json=bogus)
    assert r.status_code == 422
    # the schema's field (the unit is part of its value)
    assert [e["field"] for e in r.json()["errors"]] == ["pipe.L"]


def test_plots_in_hz(client: TestClient) -> None:
    """?frequency_unit=Hz relabels the frequency axis (the data stay rad/s); a unit the
    plot does not offer is a 422 naming the query parameter."""
    key = client.post("/v1/simulations", json=_body(100.0)).json()["key"]
    plain = client.get(f"/v1/results/{key}/plots/frequency.svg")
    hz = client.get(f"/v1/results/{key}/plots/frequency.svg?frequency_unit=Hz")
    assert plain.status_code == hz.status_code == 200
    assert "frequency ω [rad/s]" in plain.text and "frequency ω [Hz]" in hz.text
    assert plain.headers["etag"] != hz.headers["etag"]
    bad = client.get(f"/v1/results/{key}/plots/frequency.svg?frequency_unit=furlong")
    assert bad.status_code == 422
    assert [e["field"] for e in bad.json()["errors"]] == ["frequency_unit"]
