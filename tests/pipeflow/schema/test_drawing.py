"""A pipe from its drawing (issue 34, item 7): diameters, densities, material and fluid
names instead of E, I, M1, M2.

The numbers are checked against the issue's formulas evaluated here, for a 1 inch
schedule 40 steel pipe (ASME B36.10: D = 33.4 mm, t = 3.38 mm) full of water; the keys
of today's explicit requests against the keys computed before the drawing form existed.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import pytest
from pydantic import ValidationError

from pipeflow.schema.frequency import HAMMER_EXAMPLE, WATERFALL_EXAMPLE, FrequencyResponseSpec
from pipeflow.schema.keys import canonical_key
from pipeflow.schema.simulation import PAPER_EXAMPLE, PipeSpec, SimulationSpec
from pipeflow.schema.stability import StabilitySpec

D, T = 33.4e-3, 3.38e-3  # 1" schedule 40 [m]
d = D - 2 * T
I_HAND = math.pi * (D**4 - d**4) / 64  # [m^4]
M1_HAND = 7850.0 * math.pi * (D**2 - d**2) / 4  # steel [kg/m]
M2_HAND = 998.0 * math.pi * d**2 / 4  # water at 20 C [kg/m]


def _sim(pipe: dict[str, Any]) -> dict[str, Any]:
    body = copy.deepcopy(PAPER_EXAMPLE)
    body["pipe"] = pipe
    return body


def _key(body: dict[str, Any]) -> str:
    return canonical_key("simulation", SimulationSpec.model_validate(body).canonical())


def test_hand_numbers_of_a_one_inch_schedule_40_pipe() -> None:
    # by hand: d = 26.64 mm, I = 3.636e-8 m^4, M1 = 2.50 kg/m, M2 = 0.556 kg/m
    assert I_HAND == pytest.approx(3.6365e-8, rel=1e-4)
    assert M1_HAND == pytest.approx(2.5023, rel=1e-4)
    pipe = PipeSpec.model_validate(
        {"L": 2.0, "outer_diameter": D, "wall_thickness": T, "material": "steel", "fluid": "water"}
    )
    assert pipe.E == 200e9
    assert pipe.I == pytest.approx(I_HAND, rel=1e-14)
    assert pipe.M1 == pytest.approx(M1_HAND, rel=1e-14)
    assert pipe.M2 == pytest.approx(M2_HAND, rel=1e-14)


def test_drawing_form_has_the_key_of_the_explicit_form() -> None:
    explicit = {"E": 200e9, "I": I_HAND, "L": 2.0, "M1": M1_HAND, "M2": M2_HAND}
    by_values = {
        "E": {"value": 200, "unit": "GPa"},
        "L": 2.0,
        "outer_diameter": {"value": 33.4, "unit": "mm"},
        "inner_diameter": {"value": 26.64, "unit": "mm"},
        "density": 7850.0,
        "fluid_density": 998.0,
    }
    by_names = {"L": 2.0, "outer_diameter": D, "wall_thickness": T, "material": "steel"}
    by_names["fluid"] = "water"
    canon = SimulationSpec.model_validate(_sim(by_names)).canonical()
    assert set(canon["pipe"]) == set(
        SimulationSpec.model_validate(_sim(explicit)).canonical()["pipe"]
    )
    # the same floating-point numbers: the derived form is keyed as the explicit one
    derived = PipeSpec.model_validate(by_values)
    same = {"E": derived.E, "I": derived.I, "L": 2.0, "M1": derived.M1, "M2": derived.M2}
    assert _key(_sim(by_values)) == _key(_sim(same))
    assert derived.I == pytest.approx(I_HAND, rel=1e-12)
    assert _key(_sim(by_names)) == _key(_sim(dict(PipeSpec.model_validate(by_names).model_dump())))
    assert _key(_sim(by_names)) != _key(PAPER_EXAMPLE)


def test_explicit_requests_keep_their_keys() -> None:
    # computed on main before the drawing form (commit 5254bca)
    assert _key(PAPER_EXAMPLE) == "59c7e181a7d73a007cdf04433f7e13ab931a1a1145aa753c018c9e637de0e517"
    freq = FrequencyResponseSpec.model_validate
    assert canonical_key("frequency", freq(HAMMER_EXAMPLE).canonical()) == (
        "561cd800aa89ed09721010d8f18f71f5b475cd078ce9d9676ace88018080be26"
    )
    assert canonical_key("frequency", freq(WATERFALL_EXAMPLE).canonical()) == (
        "ad127f7e3e3682fb64515a8e879a955f309bf8be1437bf0ddb7214e4669b8b30"
    )
    stab = StabilitySpec.model_json_schema()["examples"][0]
    assert canonical_key("stability", StabilitySpec.model_validate(stab).canonical()) == (
        "ac533ff8496f5a1020e651d7efdf527757a59e5aa228c7336577cb36bbaf1f99"
    )
    # a table profile without the later 'after' field (issue 32) keeps its key (68aa4a7)
    table = {"kind": "table", "t": [0, 0.5, 1.0], "values": [0, 0.2, 0.4]}
    tabled = {**PAPER_EXAMPLE, "flow": {**PAPER_EXAMPLE["flow"], "velocity": table}}
    assert canonical_key("simulation", SimulationSpec.model_validate(tabled).canonical()) == (
        "1c324510c70e628c1dab6a45f43a8b44fcd8cfa10169f7a85de7f193725d0225"
    )


def test_material_with_overrides() -> None:
    pipe = PipeSpec.model_validate(
        {
            "L": 1.0,
            "E": 210e9,
            "material": "steel",
            "outer_diameter": D,
            "inner_diameter": d,
            "density": 7800.0,
            "fluid": "sea water",
        }
    )
    assert pipe.E == 210e9
    assert pipe.M1 == pytest.approx(7800.0 * math.pi * (D**2 - d**2) / 4, rel=1e-14)
    assert pipe.M2 == pytest.approx(1025.0 * math.pi * d**2 / 4, rel=1e-14)
    # a material alone gives E for an explicit section
    only = PipeSpec.model_validate({"L": 1.0, "I": 1e-8, "M1": 1.0, "M2": 0.5, "material": "PVC"})
    assert only.E == 3.0e9


def _refusal(pipe: dict[str, Any]) -> tuple[str, str]:
    with pytest.raises(ValidationError) as info:
        SimulationSpec.model_validate(_sim(pipe))
    err = info.value.errors()[0]
    cause = (err.get("ctx") or {}).get("error")
    return str(err["msg"]), ".".join(map(str, getattr(cause, "loc", err["loc"])))


@pytest.mark.parametrize(
    ("pipe", "field", "words"),
    [
        (
            {
                "E": 2e11,
                "I": 1e-8,
                "L": 1,
                "M1": 1.0,
                "fluid": "water",
                "outer_diameter": D,
                "inner_diameter": d,
            },
            "I",
            "I and outer_diameter both given",
        ),
        (
            {
                "E": 2e11,
                "L": 1,
                "M1": 1.0,
                "M2": 0.1,
                "outer_diameter": D,
                "inner_diameter": d,
                "density": 7850.0,
            },
            "M1",
            "M1 and density both given",
        ),
        (
            {
                "E": 2e11,
                "L": 1,
                "M1": 1.0,
                "M2": 0.1,
                "outer_diameter": D,
                "inner_diameter": d,
                "fluid_density": 998.0,
            },
            "M2",
            "M2 and fluid_density both given",
        ),
        (
            {
                "L": 1,
                "material": "steel",
                "outer_diameter": D,
                "inner_diameter": d,
                "wall_thickness": T,
                "fluid": "water",
            },
            "wall_thickness",
            "both given",
        ),
        (
            {
                "L": 1,
                "material": "steel",
                "outer_diameter": D,
                "inner_diameter": D,
                "fluid": "water",
            },
            "inner_diameter",
            "not less than outer_diameter",
        ),
        (
            {
                "L": 1,
                "material": "steel",
                "outer_diameter": D,
                "wall_thickness": D,
                "fluid": "water",
            },
            "wall_thickness",
            "outer_diameter / 2",
        ),
        (
            {"L": 1, "material": "steel", "outer_diameter": D, "fluid": "water"},
            "inner_diameter",
            "needs inner_diameter or wall_thickness",
        ),
        (
            {"L": 1, "material": "steel", "outer_diameter": D, "inner_diameter": d},
            "M2",
            "fluid_density or fluid",
        ),
        (
            {
                "L": 1,
                "material": "steal",
                "outer_diameter": D,
                "inner_diameter": d,
                "fluid": "water",
            },
            "material",
            "did you mean 'steel'",
        ),
        (
            {
                "L": 1,
                "material": "steel",
                "outer_diameter": -D,
                "inner_diameter": d,
                "fluid": "water",
            },
            "outer_diameter",
            "greater than 0",
        ),
        (
            {
                "L": 1,
                "material": "steel",
                "outer_diameter": {"value": 1, "unit": "s"},
                "inner_diameter": d,
                "fluid": "water",
            },
            "outer_diameter",
            "is a time",
        ),
        (
            {
                "L": 1,
                "material": "steel",
                "outer_diameter": "33.4 mm",
                "inner_diameter": d,
                "fluid": "water",
            },
            "outer_diameter",
            'as {"value": 33.4, "unit": "mm"}',
        ),
    ],
)
def test_mixed_or_incomplete_drawings_are_refused_naming_the_field(
    pipe: dict[str, Any], field: str, words: str
) -> None:
    message, loc = _refusal(pipe)
    assert words in message
    assert loc.endswith(field)


def test_m2_and_fluid_density_clash() -> None:
    message, loc = _refusal(
        {
            "E": 2e11,
            "L": 1,
            "M1": 1.0,
            "M2": 0.1,
            "material": "steel",
            "outer_diameter": D,
            "inner_diameter": d,
            "fluid_density": 998.0,
        }
    )
    # M1 from the material clashes first
    assert "M1 and material both given" in message and loc == "M1"


def test_schema_offers_both_forms() -> None:
    schema = SimulationSpec.model_json_schema()
    pipe = schema["$defs"]["PipeSpec"]
    assert pipe["required"] == ["L"]
    for name in (
        "outer_diameter",
        "inner_diameter",
        "wall_thickness",
        "density",
        "fluid_density",
        "material",
        "fluid",
    ):
        assert name in pipe["properties"]
    assert "[m]" in pipe["properties"]["outer_diameter"]["description"]
    out = SimulationSpec.model_json_schema(mode="serialization")["$defs"]["PipeSpec"]
    assert "outer_diameter" not in out["properties"]
