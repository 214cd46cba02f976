"""Quantities with their unit on input (pipeflow.schema.units, issue 24).

The conversions are checked against factors written out here (1 rpm = 2 pi / 60 rad/s,
1 Hz = 2 pi rad/s, 1 bar = 1e5 Pa, 1 mm = 1e-3 m), at 1e-15 relative (one or two
roundings of a product).  The cache key is computed from the canonical form, which holds
the SI number: the same physics in rpm or rad/s is one key.
"""

from __future__ import annotations

import copy
import math
import time
from typing import Any

import pytest
from pydantic import ValidationError

from pipeflow.errors import InvalidField
from pipeflow.schema import units
from pipeflow.schema.frequency import HAMMER_EXAMPLE, FrequencyResponseSpec
from pipeflow.schema.keys import canonical_key
from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec
from pipeflow.schema.stability import StabilitySpec
from pipeflow.schema.units import si_unit


def _body(**changes: Any) -> dict[str, Any]:
    body = copy.deepcopy(PAPER_EXAMPLE)
    for path, value in changes.items():
        node = body
        *parents, last = path.split("__")
        for p in parents:
            node = node.setdefault(p, {})
        node[last] = value
    return body


def _key(body: dict[str, Any]) -> str:
    return canonical_key("simulation", SimulationSpec.model_validate(body).canonical())


def test_rpm_and_rad_per_s_give_the_same_key() -> None:
    rpm = _body(rotation__omega0={"kind": "constant", "value": {"value": 3000, "unit": "rpm"}})
    rad = _body(rotation__omega0={"kind": "constant", "value": 100 * math.pi})
    hz = _body(rotation__omega0={"kind": "constant", "value": {"value": 50, "unit": "Hz"}})
    spec = SimulationSpec.model_validate(rpm)
    assert spec.rotation.omega0.value == pytest.approx(3000 * 2 * math.pi / 60, rel=1e-15)
    assert _key(rpm) == _key(rad) == _key(hz)
    assert _key(rpm) != _key(_body())  # 100 rad/s is another case


@pytest.mark.parametrize(
    ("path", "quantity", "si"),
    [
        ("pipe__L", {"value": 25, "unit": "mm"}, 0.025),
        ("pipe__E", {"value": 7.8, "unit": "GPa"}, 7.8e9),
        ("pipe__M1", {"value": 0.1884, "unit": "g/m"}, 1.884e-4),
        ("pipe__I", {"value": 12.1, "unit": "mm^4"}, 1.21e-11),
        ("initial__u0", {"value": 1, "unit": "mm"}, 1e-3),
        ("time__t_end", {"value": 250, "unit": "ms"}, 0.25),
        ("output__divergence_bound", {"value": 2, "unit": "mm"}, 2e-3),
        ("output__positions", [{"value": 12.5, "unit": "mm"}, 0.02], [0.0125, 0.02]),
    ],
)
def test_a_quantity_is_converted_to_the_fields_si_unit(path: str, quantity: Any, si: Any) -> None:
    spec = SimulationSpec.model_validate(_body(**{path: quantity}))
    node: Any = spec
    for p in path.split("__"):
        node = getattr(node, p)
    assert node == pytest.approx(si, rel=1e-15)


def test_profile_members_take_the_holders_unit() -> None:
    """Polynomial coefficients c_k in unit/s^k: 40 cm/s^2 is 0.4 m/s^2."""
    body = _body(
        flow__velocity={"kind": "polynomial", "coefficients": [0, {"value": 40, "unit": "cm/s^2"}]}
    )
    assert SimulationSpec.model_validate(body).flow.velocity.coefficients == pytest.approx(
        [0.0, 0.4], rel=1e-15
    )
    assert _key(body) == _key(_body())  # the paper's v = 0.4 t


def test_pressure_in_bar_and_frequencies_in_hz_elsewhere() -> None:
    stab = StabilitySpec.model_validate(
        {
            "pipe": {**PAPER_EXAMPLE["pipe"], "E": {"value": 78000, "unit": "bar"}},
            "velocity_range": [0, {"value": 108, "unit": "km/h"}],
        }
    )
    assert stab.pipe.E == pytest.approx(7.8e9, rel=1e-15)
    assert stab.velocity_range[1] == pytest.approx(30.0, rel=1e-15)
    frf = FrequencyResponseSpec.model_validate(
        {**HAMMER_EXAMPLE, "frequencies": {"values": [{"value": 10, "unit": "Hz"}, 5.0]}}
    )
    assert frf.frequencies.values == pytest.approx([20 * math.pi, 5.0], rel=1e-15)


@pytest.mark.parametrize(
    ("path", "quantity", "field", "words"),
    [
        ("pipe__L", {"value": 3, "unit": "rpm"}, ("pipe", "L"), "not a length [m]"),
        (
            "rotation__omega0",
            {"kind": "constant", "value": {"value": 3, "unit": "m"}},
            ("rotation", "omega0", "value"),
            "is a length, not",
        ),
        ("pipe__E", {"value": 3, "unit": "furlongs per bogus"}, ("pipe", "E", "unit"), "unknown"),
        ("pipe__E", {"value": 3, "unit": "Pa", "x": 1}, ("pipe", "E"), "'unit'"),
        ("pipe__E", {"value": "3", "unit": "Pa"}, ("pipe", "E", "value"), "finite number"),
        ("pipe__L", {"value": -25, "unit": "mm"}, ("pipe", "L"), "greater than 0"),
    ],
)
def test_a_wrong_quantity_is_refused_naming_the_field(
    path: str, quantity: Any, field: tuple[str, ...], words: str
) -> None:
    with pytest.raises(ValidationError) as err:
        SimulationSpec.model_validate(_body(**{path: quantity}))
    (e,) = err.value.errors()
    cause = (e.get("ctx") or {}).get("error")
    loc = tuple(e["loc"]) + (cause.loc if isinstance(cause, InvalidField) else ())
    assert loc == field, e
    assert words in e["msg"], e["msg"]


def test_the_schema_offers_the_quantity_form_where_a_unit_applies() -> None:
    top = SimulationSpec.model_json_schema()
    schema = top["$defs"]
    length = schema["PipeSpec"]["properties"]["L"]
    assert length["anyOf"][0]["type"] == "number"
    assert length["anyOf"][1] == {"$ref": "#/$defs/Quantity"}
    assert schema["Quantity"]["required"] == ["value", "unit"]
    assert "[m]" in length["description"]
    assert top["properties"]["modes"]["type"] == "integer"  # no unit
    # one schema in both modes (no -Input/-Output split of echoed request models)
    answer = SimulationSpec.model_json_schema(mode="serialization")["$defs"]["PipeSpec"]
    assert answer["properties"]["L"] == length


def test_units_are_read_from_the_descriptions() -> None:
    assert si_unit("Pipe length [m].") == "m"
    assert si_unit("[v_min, v_max] flow velocities [m/s], increasing") == "m/s"
    assert si_unit("Viscous ratio [-] (eq. (3.1), [1/s])") is None
    assert si_unit("Number of modes.") is None


def test_a_constant_profile_without_its_kind_is_not_a_quantity() -> None:
    """{"value": 100} is a constant spin whose kind is left to its default (the stability
    form sends it so), not a quantity missing its unit."""
    body = {"pipe": PAPER_EXAMPLE["pipe"], "velocity_range": [0, 60]}
    spec = StabilitySpec.model_validate({**body, "rotation": {"omega0": {"value": 100}}})
    assert spec.rotation.omega0.value == 100
    rpm = {"omega0": {"value": {"value": 955, "unit": "rpm"}}}
    assert StabilitySpec.model_validate({**body, "rotation": rpm}).rotation.omega0.value == (
        pytest.approx(955 * 2 * math.pi / 60, rel=1e-15)
    )


def test_a_request_of_plain_numbers_is_scanned_once_and_converts_nothing(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Issue 24, item 4: the hook ran ``convert_fields`` on every model of every request
    (11 calls for the paper's example); an input without a quantity anywhere is scanned
    once by its outermost model and no model converts.  An input with one still converts
    (the count shows the hook is live in this test)."""
    calls: list[str] = []
    real = units.convert_fields

    def counting(model: type[Any], data: Any) -> Any:
        calls.append(model.__name__)
        return real(model, data)

    monkeypatch.setattr(units, "convert_fields", counting)
    SimulationSpec.model_validate(copy.deepcopy(PAPER_EXAMPLE))
    assert calls == []
    spec = SimulationSpec.model_validate(_body(pipe__L={"value": 25, "unit": "mm"}))
    assert spec.pipe.L == pytest.approx(0.025, rel=1e-15)
    assert "PipeSpec" in calls


def test_the_quantity_free_marks_last_only_as_long_as_their_validation() -> None:
    """The dicts marked quantity-free are so for the validation that scanned them: the
    same dict given a quantity afterwards is converted, and an input validated inside
    another validation (a validator checking further data) is scanned on its own."""
    body = copy.deepcopy(PAPER_EXAMPLE)
    SimulationSpec.model_validate(body)
    body["pipe"]["L"] = {"value": 25, "unit": "mm"}
    assert SimulationSpec.model_validate(body).pipe.L == pytest.approx(0.025, rel=1e-15)

    inner = _body(rotation__omega0={"kind": "constant", "value": {"value": 3000, "unit": "rpm"}})

    def handler(data: Any) -> Any:  # the outer model's validation validating other input
        return SimulationSpec.model_validate(inner)

    spec = units.validate(SimulationSpec, copy.deepcopy(PAPER_EXAMPLE), handler)
    assert spec.rotation.omega0.value == pytest.approx(100 * math.pi, rel=1e-15)


@pytest.mark.parametrize(
    "unit",
    [
        *("mm", "g/cm", "kg*m^2", "kg / m ** 3", "(m/s)**2", "1/s", "m s^-1", "N m", "m²"),
        *("m⁻¹", "°/s", "parsecs per fortnight^2", "square meter", "µm", "((m))"),
    ],
)
def test_the_unit_grammar_takes_names_operators_and_small_integer_powers(unit: str) -> None:
    assert units.unit_grammar(unit), unit


@pytest.mark.parametrize(
    "unit",
    [
        *("9**9**7 mm", "9 mm", "2*m", "1e9 m", "1.0/s", "m**0.5", "m**100", "m**2**3", "**2"),
        *("m(s)", "m 1", "m*", "(m", "m)", "(((((m)))))", "m-s", "m,s", "m; s", "m +s", "m^2s"),
        *("__import__('os').getcwd()", "", " "),
    ],
)
def test_the_unit_grammar_refuses_numbers_calls_and_chained_powers(unit: str) -> None:
    assert not units.unit_grammar(unit), unit


def test_a_number_expression_in_a_unit_is_refused_before_pint_evaluates_it() -> None:
    """Issue 34, item 2: pint evaluated ``9**9**7`` (2.8 s of a core; ``9**9**8`` ~100 s)
    before refusing the unit.  The grammar refuses it without pint: well within a second
    here (a generous bound: it takes microseconds), naming the field."""
    body = _body(pipe__L={"value": 25, "unit": "9**9**8 mm"})
    start = time.perf_counter()
    with pytest.raises(ValidationError) as err:
        SimulationSpec.model_validate(body)
    assert time.perf_counter() - start < 1.0
    (e,) = err.value.errors()
    assert e["loc"] == ("pipe",) and e["ctx"]["error"].loc == ("L", "unit")
    assert "'9**9**8 mm' is not a unit" in e["msg"]


def test_many_quantities_convert_by_a_cached_factor(monkeypatch: pytest.MonkeyPatch) -> None:
    """A table of 10,000 quantities (the most a profile holds) in one unit asks pint twice
    to parse a unit (the given and the field's) and twice to convert (the factor, and 0 to
    check that it is one), whatever the count: each value is then multiplied by the cached
    factor.  Before, pint parsed both units and converted once per value (20,000 parses,
    0.55 s of the event loop here for one request); the values are pint's."""
    ureg = units.registry()
    calls = {"parse_units": 0, "Quantity": 0}
    for name in calls:
        real = getattr(ureg, name)

        def counting(*args: Any, _real: Any = real, _name: str = name) -> Any:
            calls[_name] += 1
            return _real(*args)

        monkeypatch.setattr(ureg, name, counting)
    units.parsed_unit.cache_clear()
    units.conversion.cache_clear()
    n = 10_000
    table = {
        "kind": "table",
        "t": [i * 1e-3 for i in range(n)],
        "values": [{"value": 1.0 + i, "unit": "mm/s"} for i in range(n)],
    }
    velocity = SimulationSpec.model_validate(_body(flow__velocity=table)).flow.velocity
    assert calls == {"parse_units": 2, "Quantity": 2}
    assert velocity.values[0] == 1e-3 and velocity.values[-1] == pytest.approx(10.0, rel=1e-15)


def test_a_request_may_use_a_bounded_number_of_different_units() -> None:
    """Each new unit string costs pint a parse (up to ~1 ms): a request naming thousands
    of different ones (``mm*s/s``, ``mm*s*s/s/s``, ...) would cost seconds; past
    MAX_UNITS_PER_REQUEST the first extra one is refused, naming its field.  The same unit
    repeated costs nothing more, and the count is per request."""
    n = units.MAX_UNITS_PER_REQUEST
    spellings = ["mm/s", "cm/s", "m/s", "km/h", "mm*Hz", "cm*Hz", "m*Hz", "in/s", "ft/s"]
    spellings += [f"mm/s*(s/s)**{k}" for k in range(1, 60)]
    table = {
        "kind": "table",
        "t": [float(i) for i in range(n + 1)],
        "values": [{"value": 1.0, "unit": u} for u in spellings[: n + 1]],
    }
    with pytest.raises(ValidationError) as err:
        SimulationSpec.model_validate(_body(flow__velocity=table))
    (e,) = err.value.errors()
    assert e["ctx"]["error"].loc == ("velocity", "values", str(n), "unit")
    assert f"at most {n} different units" in e["msg"]
    table["values"] = table["values"][:n]
    table["t"] = table["t"][:n]
    for _ in range(2):  # twice: the count is per request
        spec = SimulationSpec.model_validate(_body(flow__velocity=table))
        assert spec.flow.velocity.values[:3] == pytest.approx([1e-3, 1e-2, 1.0], rel=1e-15)
