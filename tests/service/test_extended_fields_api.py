"""The extended model's fields over HTTP (issue 14): accepted, run, reported, and a bad
value is a 422 problem naming its JSON field."""

from __future__ import annotations

import copy
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.service.conftest import SMALL


def _extended() -> dict[str, Any]:
    body = copy.deepcopy(SMALL)
    body["pipe"].update(
        damping={"kelvin_voigt": 2e-6, "viscous": 2e-4}, tip_mass=1e-7, tip_inertia=1e-13
    )
    body.setdefault("rotation", {})["hub_radius"] = 0.01
    body["plane"] = "out-of-plane"
    return body


def test_simulation_with_every_new_field(client: TestClient) -> None:
    body = _extended()
    r = client.post("/v1/simulations", json=body)
    assert r.status_code == 200, r.text
    doc = r.json()
    groups = doc["dimensionless"]
    assert groups["tip_mass_ratio"] > 0 and groups["hub_ratio"] == pytest.approx(0.4)
    assert groups["alpha"] > 0 and groups["viscous_ratio"] > 0 and groups["tip_inertia_ratio"] > 0
    assert max(doc["fundamental"]["sigma"]) < 0  # damped
    # the fields are part of the key: the paper's pipe is another computation
    plain = client.post("/v1/simulations", json=SMALL).json()
    assert plain["key"] != doc["key"]


@pytest.mark.parametrize(
    ("where", "value", "field"),
    [
        (("pipe", "damping", "kelvin_voigt"), -1.0, "pipe.damping.kelvin_voigt"),
        (("pipe", "damping", "viscous"), "lots", "pipe.damping.viscous"),
        (("pipe", "tip_mass"), -1e-3, "pipe.tip_mass"),
        (("pipe", "tip_inertia"), -1.0, "pipe.tip_inertia"),
        (("rotation", "hub_radius"), -0.5, "rotation.hub_radius"),
        (("plane",), "sideways", "plane"),
    ],
)
def test_bad_values_are_422_naming_the_field(
    client: TestClient, where: tuple[str, ...], value: Any, field: str
) -> None:
    stability = {k: _extended()[k] for k in ("pipe", "rotation", "plane")}
    for path, body in (
        ("/v1/simulations", _extended()),
        ("/v1/stability", {**stability, "velocity_range": [0, 1]}),
    ):
        node = body
        for k in where[:-1]:
            node = node[k]
        node[where[-1]] = value
        r = client.post(path, json=body)
        assert r.status_code == 422, r.text
        assert r.headers["content-type"] == "application/problem+json"
        assert field in [e["field"] for e in r.json()["errors"]], (path, r.json())


def test_stability_out_of_plane_with_damping(client: TestClient) -> None:
    body = {
        "pipe": _extended()["pipe"],
        "rotation": {"omega0": {"kind": "constant", "value": 100.0}, "hub_radius": 0.01},
        "plane": "out-of-plane",
        "modes": 6,
        "velocity_range": [0.0, 60.0],
        "points": 61,
    }
    r = client.post("/v1/stability", json=body)
    assert r.status_code == 200, r.text
    doc = r.json()
    assert doc["critical_velocity"] is not None
    assert doc["dimensionless"]["hub_ratio"] == pytest.approx(0.4)
    assert doc["dimensionless"]["alpha"] > 0


@pytest.mark.parametrize(("name", "value"), [("tip_inertia", 1e12), ("tip_mass", 1e9)])
def test_a_tip_body_beyond_the_modal_basis_is_422_naming_the_field(
    client: TestClient, name: str, value: float
) -> None:
    """J_t = 1e12 kg m^2 (schema maximum) on the paper pipe made the mass matrix singular to
    rounding (condition number 3e18): the simulation failed with 'Singular matrix' and
    /v1/stability answered 200 with the range end 54 m/s as critical velocity.  Both are
    now a 422 problem naming the field (model build: condition number above 1e12)."""
    stability = {k: _extended()[k] for k in ("pipe", "rotation", "plane")}
    for path, body in (
        ("/v1/simulations", _extended()),
        ("/v1/stability", {**stability, "velocity_range": [0, 54]}),
    ):
        body["pipe"][name] = value
        r = client.post(path, json=body)
        assert r.status_code == 422, (path, r.text)
        assert r.headers["content-type"] == "application/problem+json"
        doc = r.json()
        assert f"pipe.{name}" in [e["field"] for e in doc["errors"]], (path, doc)
        assert "condition number" in r.text
