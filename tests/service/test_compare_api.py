"""POST /v1/compare: one case with several methods (issue 4, the paper's Tables 1-2 made
reproducible on the user's own case)."""

from __future__ import annotations

import copy
from typing import Any

import pytest
from fastapi.testclient import TestClient

from pipeflow.schema.results import CompareResponse
from tests.service.conftest import SMALL


def _body(**changes: Any) -> dict[str, Any]:
    sim = copy.deepcopy(SMALL)
    # v = 0.4 t: time-variant, so cma is an approximation and magnus the accurate one
    sim["flow"] = {"velocity": {"kind": "polynomial", "coefficients": [0.0, 0.4]}}
    body: dict[str, Any] = {"simulation": sim, "methods": ["cma", "magnus", "rk4"]}
    body.update(changes)
    return body


def test_compare_ranks_methods_and_is_cached(client: TestClient) -> None:
    """magnus (error estimate ~1e-9) is the baseline; cma differs from it by its
    commutator error (> 1e-7 on this case) and rk4 by its truncation error; the second
    identical request is a cache hit with the same numbers."""
    # refresh: computed here whichever test of the module stored this case first
    first = client.post("/v1/compare", params={"refresh": "true"}, json=_body())
    assert first.status_code == 200, first.text
    assert first.headers["x-cache"] == "MISS"
    doc = first.json()
    CompareResponse.model_validate(doc)
    assert doc["baseline"] == "magnus"
    rows = {r["method"]: r for r in doc["methods"]}
    assert set(rows) == {"cma", "magnus", "rk4"}
    assert rows["magnus"]["difference_from_baseline"] == 0.0
    assert rows["cma"]["tip_difference_from_baseline"] > 1e-7
    assert all(r["solve_seconds"] > 0 for r in rows.values())
    assert any("estimated relative error" in w for w in rows["cma"]["warnings"]) or (
        rows["cma"]["estimated_relative_error"] < 1e-4
    )
    second = client.post("/v1/compare", json=_body())
    assert second.headers["x-cache"] == "HIT"
    assert {**second.json(), "cached": False} == doc
    stored = client.get(f"/v1/results/{doc['key']}")
    assert stored.status_code == 200 and stored.json()["baseline"] == "magnus"


def test_compare_key_ignores_the_simulation_method(client: TestClient) -> None:
    a = _body()
    b = _body()
    b["simulation"]["method"] = "rk4"
    ka = client.post("/v1/compare", json=a).json()["key"]
    kb = client.post("/v1/compare", json=b).json()["key"]
    assert ka == kb


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"methods": ["cma", "bogus"]}, "methods"),
        ({"methods": ["cma", "cma"]}, "methods"),
        ({"methods": []}, "methods"),
        ({"simulation": {"modes": 3}}, "simulation.pipe"),
        ({"extra": 1}, "extra"),
    ],
)
def test_compare_errors_name_the_field(
    client: TestClient, changes: dict[str, Any], field: str
) -> None:
    r = client.post("/v1/compare", json=_body(**changes))
    assert r.status_code == 422
    assert r.headers["content-type"] == "application/problem+json"
    fields = [e["field"] for e in r.json()["errors"]]
    assert any(f is not None and f.startswith(field) for f in fields), fields


def test_unknown_method_points_at_its_index(client: TestClient) -> None:
    """The field validator's "methods.1: ..." on ``methods`` is ``methods.1``, not
    ``methods.methods.1``."""
    r = client.post("/v1/compare", json=_body(methods=["cma", "bogus"]))
    assert r.status_code == 422
    error = r.json()["errors"][0]
    assert (error["field"], error["pointer"]) == ("methods.1", "#/methods/1")
