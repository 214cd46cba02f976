"""A pipe from its drawing over HTTP (issue 34, item 7): the drawing and the explicit pipe
it stands for are one result; a quantity given both ways is a 422 naming the fields."""

from __future__ import annotations

import copy
from typing import Any

from fastapi.testclient import TestClient

from pipeflow.schema.simulation import PAPER_EXAMPLE, PipeSpec

#: a 1" schedule 40 steel pipe, 1 m, full of water
DRAWING = {
    "L": 1.0,
    "outer_diameter": {"value": 33.4, "unit": "mm"},
    "wall_thickness": {"value": 3.38, "unit": "mm"},
    "material": "steel",
    "fluid": "water",
}


def _body(pipe: dict[str, Any]) -> dict[str, Any]:
    body = copy.deepcopy(PAPER_EXAMPLE)
    body["pipe"] = pipe
    body["time"] = {"t_end": 0.05, "samples": 51}
    body["modes"] = 3
    return body


def test_the_drawing_is_the_explicit_request(client: TestClient) -> None:
    a = client.post("/v1/simulations", json=_body(DRAWING))
    assert a.status_code == 200, a.text
    explicit = PipeSpec.model_validate(DRAWING).model_dump()
    assert set(explicit) == {"E", "I", "L", "M1", "M2", "damping", "tip_mass", "tip_inertia"}
    b = client.post("/v1/simulations", json=_body(explicit))
    assert b.status_code == 200, b.text
    assert a.json()["key"] == b.json()["key"] and b.json()["cached"] is True


def test_both_ways_is_a_422_naming_the_field(client: TestClient) -> None:
    r = client.post("/v1/simulations", json=_body(dict(DRAWING, I=1e-8)))
    assert r.status_code == 422, r.text
    (error,) = r.json()["errors"]
    assert error["field"] == "pipe.I"
    assert "I and outer_diameter both given" in error["message"]
    r = client.post("/v1/simulations", json=_body(dict(DRAWING, material="stainles")))
    assert r.status_code == 422, r.text
    (error,) = r.json()["errors"]
    assert error["field"] == "pipe.material"
    assert "did you mean 'stainless'?" in error["message"]


def test_422_messages_are_readable(client: TestClient) -> None:
    """Issue 34, item 8: "3000 rpm" as text is shown the {"value", "unit"} form, an
    unknown field gets a "did you mean", a validator's refusal has no "Value error,"."""
    body = _body(DRAWING)
    body["rotation"] = {"omega0": {"kind": "constant", "value": "3000 rpm"}}
    r = client.post("/v1/simulations", json=body)
    assert r.status_code == 422, r.text
    (error,) = r.json()["errors"]
    assert error["field"] == "rotation.omega0.value"
    assert error["message"].endswith('as {"value": 3000, "unit": "rpm"}')
    body = _body(dict(DRAWING, fluid="water", wall_thicknes=0.003))
    r = client.post("/v1/simulations", json=body)
    assert r.status_code == 422, r.text
    (error,) = r.json()["errors"]
    assert error["field"] == "pipe.wall_thicknes"
    assert error["message"] == "Extra inputs are not permitted; did you mean 'wall_thickness'?"
    r = client.post("/v1/simulations", json=_body(dict(DRAWING, wall_thickness=0.1)))
    (error,) = r.json()["errors"]
    assert error["message"].startswith("wall_thickness = 0.1 m is more than outer_diameter / 2")
