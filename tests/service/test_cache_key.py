"""Cache keys: equivalent requests share one key; a change that matters changes it."""

from __future__ import annotations

import copy
import json
from typing import Any

from fastapi.testclient import TestClient

from pipeflow.computations.registry import SIMULATION, STABILITY
from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec
from pipeflow.schema.stability import StabilitySpec
from service.keys import keyed


def _key(body: dict[str, Any]) -> str:
    return keyed(SIMULATION, SimulationSpec.model_validate(body)).key


def test_the_kind_salts_the_key() -> None:
    """Two computations with equal normal forms never share a key."""
    body = {"pipe": PAPER_EXAMPLE["pipe"], "velocity_range": [0.0, 1.0]}
    spec = StabilitySpec.model_validate(body)
    assert keyed(STABILITY, spec).key != keyed(SIMULATION, spec).key


def test_key_order_is_irrelevant() -> None:
    body = copy.deepcopy(PAPER_EXAMPLE)
    reordered = {k: body[k] for k in reversed(list(body))}
    reordered["pipe"] = dict(reversed(list(body["pipe"].items())))
    assert json.dumps(reordered) != json.dumps(body)
    assert _key(reordered) == _key(body)


def test_int_and_float_are_equal() -> None:
    body = copy.deepcopy(PAPER_EXAMPLE)
    as_ints = copy.deepcopy(body)
    as_ints["rotation"]["omega0"]["value"] = 100
    as_ints["time"]["t_end"] = 1
    as_ints["pipe"]["E"] = 7800000000
    assert _key(as_ints) == _key(body)


def test_defaults_omitted_or_spelled_out() -> None:
    minimal = {"pipe": PAPER_EXAMPLE["pipe"]}
    explicit = SimulationSpec.model_validate(minimal).model_dump(mode="json")
    assert _key(explicit) == _key(minimal)
    # options the chosen method does not read do not change the key
    assert _key({**minimal, "options": {"rtol": 1e-6}}) == _key(minimal)


def test_changes_that_matter_change_the_key() -> None:
    base = _key(PAPER_EXAMPLE)
    changed = [
        {**PAPER_EXAMPLE, "modes": 9},
        {**PAPER_EXAMPLE, "pipe": {**PAPER_EXAMPLE["pipe"], "E": 7.8e9 * (1 + 1e-12)}},
        {**PAPER_EXAMPLE, "method": "rk4"},
        {**PAPER_EXAMPLE, "time": {"t_end": 1.0, "samples": 2000}},
    ]
    keys = {_key(body) for body in changed}
    assert base not in keys and len(keys) == len(changed)


def test_api_reports_the_same_key(client: TestClient) -> None:
    body = {"pipe": PAPER_EXAMPLE["pipe"], "modes": 2, "time": {"samples": 51}}
    spelled = SimulationSpec.model_validate(body).model_dump(mode="json")
    first = client.post("/v1/simulations", json=body)
    second = client.post("/v1/simulations", json=spelled)
    assert first.json()["key"] == second.json()["key"] == _key(body)
    assert second.headers["x-cache"] == "HIT"
