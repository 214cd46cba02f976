"""The registry of computations: each entry is complete, and what is derived from it agrees."""

from __future__ import annotations

import copy
import dataclasses
import typing
from typing import Any

import pytest

from pipeflow.computations import registry
from pipeflow.computations.registry import COMPUTATIONS, SIMULATION, SWEEP_KINDS
from pipeflow.errors import InvalidInput
from pipeflow.io.plots import available_plots
from pipeflow.schema.keys import canonical_key
from pipeflow.schema.simulation import PAPER_EXAMPLE, MethodOptions, SimulationSpec
from pipeflow.solvers import Options
from tests.pipeflow.cases import TINY, tiny_request

#: the computations pipeflow answers (the tests register their own kinds too)
SERVED = [
    COMPUTATIONS[n]
    for n in ("simulation", "compare", "stability", *SWEEP_KINDS, "study", "frequency_response")
]


def test_every_served_computation_is_complete() -> None:
    for c in SERVED:
        assert c.cost and c.examples, c.name
        for example in c.examples.values():  # every example is a valid request of its own
            request = registry.parse(c.name, example["value"])
            assert registry.computation_for(request) is c
            if c.name in SWEEP_KINDS:  # and of the sweep kinds, told apart by kind
                assert registry.computation_for(registry.parse(SWEEP_KINDS, example["value"])) is c


def test_parse_refuses_an_unknown_name_naming_the_known_ones() -> None:
    with pytest.raises(KeyError, match=r"'nope'.*simulation, compare, stability"):
        registry.parse("nope", {})


def test_study_bases_declare_their_summary() -> None:
    """Every computation a study can vary declares its own summary columns and function."""
    from pipeflow.schema.study import BASE_MODELS

    for name, model in BASE_MODELS.items():
        c = COMPUTATIONS[name]
        assert c.request is model and c.summary_columns and c.summarize is not None, name


def test_sweep_kinds_are_the_kind_tags_of_the_sweep_models() -> None:
    tags = {
        typing.get_args(c.request.model_fields["kind"].annotation)[0]
        for c in (COMPUTATIONS[n] for n in SWEEP_KINDS)
    }
    assert tags == set(SWEEP_KINDS)


def test_method_options_are_the_library_options() -> None:
    """The request's options are the library's Options field for field, same defaults."""
    library = {f.name: f.default for f in dataclasses.fields(Options)}
    schema = {k: v.default for k, v in MethodOptions.model_fields.items()}
    assert schema == library


def test_library_parameters_map_onto_request_fields() -> None:
    """A library error naming its own parameter leaves execute() naming the request field."""

    def refuse(spec: SimulationSpec, progress: object) -> dict[str, object]:
        raise InvalidInput("no", parameter="step")

    c = dataclasses.replace(SIMULATION, run=refuse)
    with pytest.raises(InvalidInput) as err:
        c.execute(SimulationSpec.model_validate(PAPER_EXAMPLE))
    assert err.value.field == "options.step"
    assert SIMULATION.request_field("t_end") == "time.t_end"
    assert SIMULATION.request_field("unknown_name") == "unknown_name"
    assert COMPUTATIONS["compare"].request_field("step") == "simulation.options.step"


def test_execute_adds_the_plots_the_entry_names() -> None:
    spec = SimulationSpec.model_validate(
        {"pipe": PAPER_EXAMPLE["pipe"], "modes": 2, "time": {"t_end": 0.01, "samples": 5}}
    )
    out = SIMULATION.execute(spec)
    assert out["plots"] == ["tip_displacement", "damping", "frequency", "argand"]
    assert set(out["plots"]) <= set(SIMULATION.plots)


@pytest.mark.parametrize("name", sorted(TINY))
def test_every_plot_a_result_can_have_is_named_by_its_entry(name: str) -> None:
    """execute() keeps the plots its entry names: a plot kind added to pipeflow.io.plots for a
    computation must be added to the entry too, or this fails (it would be dropped)."""
    c = COMPUTATIONS[name]
    raw = c.run(tiny_request(name), None)
    raw = {"kind": name, **raw} if "kind" in c.response.model_fields else raw
    assert set(available_plots(raw)) <= set(c.plots)
    assert c.execute(tiny_request(name))["plots"] == available_plots(raw)


def _first_example(name: str) -> dict[str, Any]:
    examples = COMPUTATIONS[name].examples or {}
    return copy.deepcopy(next(iter(examples.values()))["value"])


@pytest.mark.parametrize("name", [n for n in COMPUTATIONS if COMPUTATIONS[n].examples])
def test_every_normal_form_is_a_request_again_with_the_same_key(name: str) -> None:
    """A job is recovered from its stored normal form: it must parse and keep its key (the
    state-space form once wrote bare numbers where profiles belong: a 500 on recovery)."""
    entry = COMPUTATIONS[name]
    spec = entry.request.model_validate(_first_example(name))
    again = entry.request.model_validate(spec.canonical())
    assert canonical_key(name, again.canonical()) == canonical_key(name, spec.canonical())


MOUNTED = [n for n in COMPUTATIONS if "gravity" in COMPUTATIONS[n].request.model_fields]


@pytest.mark.parametrize("name", MOUNTED)
def test_gravity_and_pressure_are_part_of_every_key(name: str) -> None:
    """Two requests that differ only in gravity or in the internal pressure (issue 31) never
    share a cache key, in every kind that takes them (the frequency response's and the state
    space's hand-written normal forms had left both out: one answer for two pipes)."""
    entry = COMPUTATIONS[name]
    base = _first_example(name)
    base["pipe"]["flow_area"] = 1e-4
    hanging = copy.deepcopy(base) | {"gravity": {"g": 9.81, "orientation": "hanging"}}
    pressed = copy.deepcopy(base)
    pressed.setdefault("flow", {})["pressure"] = 1e5
    keys = set()
    for body in (base, hanging, pressed):
        spec = entry.request.model_validate(body)
        again = entry.request.model_validate(spec.canonical())
        assert again.canonical() == spec.canonical()
        keys.add(canonical_key(name, spec.canonical()))
    assert len(keys) == 3


def test_every_kind_has_a_tiny_case() -> None:
    """The fuzz app answers every kind with its tiny case's result (tests/service/fuzz_app.py):
    a kind without one made its fake task fail on every attempt (state space: a timeout)."""
    # (a kind some test registers for itself, ``test-...``, needs none)
    assert {name for name in COMPUTATIONS if not name.startswith("test-")} == set(TINY)
