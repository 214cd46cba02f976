"""The registry of computations: each entry is complete, and what is derived from it agrees."""

from __future__ import annotations

import dataclasses
import typing

import pytest

from pipeflow.errors import InvalidInput
from pipeflow.io.plots import available_plots
from pipeflow.schema import registry
from pipeflow.schema.registry import COMPUTATIONS, SIMULATION, SWEEP_KINDS, SWEEPS
from pipeflow.schema.simulation import PAPER_EXAMPLE, MethodOptions, SimulationSpec
from pipeflow.solvers import Options
from tests.pipeflow.cases import TINY, tiny_request

SERVED = [c for c in COMPUTATIONS.values() if c.endpoint is not None]


def test_every_served_computation_is_complete() -> None:
    names = {c.name for c in SERVED}
    assert {"simulation", "compare", "stability", *SWEEP_KINDS} <= names
    for c in SERVED:
        assert c.cost and c.examples, c.name
        for example in c.examples.values():  # every OpenAPI example is a valid request
            request = registry.parse(c.endpoint, example["value"])  # type: ignore[arg-type]
            assert registry.computation_for(request) is c


def test_sweep_kinds_are_the_kind_tags_of_the_sweep_models() -> None:
    tags = {
        typing.get_args(c.request.model_fields["kind"].annotation)[0]
        for c in registry.computations_at(SWEEPS)
    }
    assert tags == set(SWEEP_KINDS)
    assert len(registry.endpoints()) == 5  # simulations, compare, stability, sweeps, studies


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
