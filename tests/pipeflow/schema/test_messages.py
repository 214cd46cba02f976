"""Readable validation messages (issue 34, item 8): no "Value error," prefix, the
{"value", "unit"} form for a number sent as text with its unit, a "did you mean" for an
unknown field or unit."""

from __future__ import annotations

import copy
from typing import Any

import pytest
from pydantic import ValidationError

from pipeflow.schema import messages
from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec


def _errors(body: dict[str, Any]) -> list[tuple[str, str]]:
    with pytest.raises(ValidationError) as caught:
        SimulationSpec.model_validate(body)
    return [
        (".".join(map(str, e["loc"])), messages.message(e, SimulationSpec))
        for e in caught.value.errors()
    ]


def test_a_number_with_its_unit_as_text_is_shown_the_quantity_form() -> None:
    body = copy.deepcopy(PAPER_EXAMPLE)
    body["rotation"]["omega0"] = {"kind": "constant", "value": "3000 rpm"}
    [(loc, text)] = _errors(body)
    assert loc == "rotation.omega0.constant.value"
    assert text == (
        "Input should be a valid number; '3000 rpm' is text: send a number in the field's "
        'SI unit, or the number with its unit as {"value": 3000, "unit": "rpm"}'
    )
    body["rotation"]["omega0"]["value"] = "fast"  # no unit in it: no hint
    assert _errors(body)[0][1] == "Input should be a valid number"


def test_unknown_fields_get_a_did_you_mean() -> None:
    body = copy.deepcopy(PAPER_EXAMPLE)
    body["rotaton"] = body.pop("rotation")
    body["pipe"]["outer_diamter"] = 0.03
    found = dict(_errors(body))
    assert found["rotaton"] == "Extra inputs are not permitted; did you mean 'rotation'?"
    # the drawing's fields replace pipe's before pydantic sees the rest: the unknown one
    assert found["pipe.outer_diamter"].endswith("did you mean 'outer_diameter'?")
    body = copy.deepcopy(PAPER_EXAMPLE)
    body["zzz"] = 1
    assert dict(_errors(body))["zzz"] == "Extra inputs are not permitted"


def test_validator_messages_lose_the_prefix_and_units_get_a_did_you_mean() -> None:
    body = copy.deepcopy(PAPER_EXAMPLE)
    body["pipe"].update(M1=0.0, M2=0.0)
    [(_, text)] = _errors(body)
    assert text == "M1 + M2 must be >= 1e-15 kg/m"
    body = copy.deepcopy(PAPER_EXAMPLE)
    body["rotation"]["omega0"]["value"] = {"value": 3000, "unit": "rmp"}
    [(_, text)] = _errors(body)
    assert text.endswith("value.unit: unknown unit 'rmp'; did you mean 'rpm'?")


def test_an_unknown_method_gets_a_did_you_mean() -> None:
    body = copy.deepcopy(PAPER_EXAMPLE)
    body["method"] = "magnsu"
    [(loc, text)] = _errors(body)
    assert (loc, text) == ("method", "unknown method 'magnsu'; did you mean 'magnus'?")
    body["method"] = "zzz"
    assert _errors(body)[0][1].startswith("unknown method 'zzz'; choose one of ")
