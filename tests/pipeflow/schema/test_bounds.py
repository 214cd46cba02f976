"""Every request's estimated cost is bounded at validation (a 422 naming the field, the
bound and what fits), and a pipe whose bending stiffness underflows is refused alike by
every method (defects of an outside reliability audit)."""

from __future__ import annotations

import copy
import re
from typing import Any

import pytest
from pydantic import ValidationError

from pipeflow.computations import registry
from pipeflow.computations.registry import COMPUTATIONS, SWEEP_KINDS
from pipeflow.errors import InvalidInput
from pipeflow.model import Pipe
from pipeflow.schema.simulation import PAPER_EXAMPLE
from pipeflow.solvers import SOLVERS


def _refusal(kind: str, body: dict[str, Any]) -> tuple[str, str]:
    """``(field, message)`` of the validation refusal of ``body`` as a ``kind`` request."""
    with pytest.raises(ValidationError) as info:
        registry.parse(kind, body)
    err = info.value.errors()[0]
    inner = getattr((err.get("ctx") or {}).get("error"), "loc", ())
    return ".".join(str(p) for p in (*err["loc"], *inner)), err["msg"]


def _simulation(**changes: Any) -> dict[str, Any]:
    body = copy.deepcopy(PAPER_EXAMPLE)
    body.update(changes)
    return body


def _positions(count: int) -> list[float]:
    L = PAPER_EXAMPLE["pipe"]["L"]
    return [L * (i + 1) / (count + 1) for i in range(count)]


#: the audit's request: 200,001 samples x 64 positions x the modal state at 40 modes
AUDIT = _simulation(
    modes=40,
    time={"t_end": 1.0, "samples": 200_001},
    output={"positions": _positions(64), "modal": True, "eigen_modes": 40},
)


def test_the_audits_simulation_is_refused_naming_samples_and_what_fits() -> None:
    field, message = _refusal("simulation", AUDIT)
    assert field == "time.samples"
    assert "200001 samples" in message and "64 positions" in message
    assert "exceeds the output budget of 2,000,000 values" in message
    most = int(re.search(r"at most (\d+) samples with these outputs", message).group(1))
    # the largest count stated fits, one more does not
    assert registry.parse("simulation", {**AUDIT, "time": {"t_end": 1.0, "samples": most}})
    field, _ = _refusal("simulation", {**AUDIT, "time": {"t_end": 1.0, "samples": most + 1}})
    assert field == "time.samples"


def test_the_output_estimate_bounds_the_document() -> None:
    """The estimate is an upper bound of the numbers the answer holds."""
    body = _simulation(
        modes=4,
        time={"t_end": 0.05, "samples": 301},
        output={
            "positions": _positions(3),
            "modal": True,
            "eigen_modes": 3,
            "eigen_samples": 41,
            "mode_shapes": {"times": [0.0, 0.05], "points": 11},
        },
    )
    request = registry.parse("simulation", body)
    doc = COMPUTATIONS["simulation"].execute(request)

    def numbers(node: Any) -> int:
        if isinstance(node, dict):
            return sum(numbers(v) for k, v in node.items() if k not in ("diagnostics",))
        if isinstance(node, list):
            return sum(numbers(v) for v in node)
        return int(isinstance(node, float))

    estimate = COMPUTATIONS["simulation"].estimate(request)
    assert estimate is not None
    counted = numbers(doc)
    assert counted <= estimate.units < 1.2 * counted + 100


def test_a_comparison_holds_each_methods_run_within_the_budget() -> None:
    """Each method's run fits alone, three of them do not: refused naming the samples."""
    sim = _simulation(time={"t_end": 1.0, "samples": 20_001}, output={"positions": _positions(64)})
    assert registry.parse("simulation", sim)
    field, message = _refusal("compare", {"simulation": sim, "methods": ["cma", "magnus", "rk4"]})
    assert field == "simulation.time.samples"
    assert "3 methods x" in message and "and 3 methods" in message
    assert registry.parse("compare", {"simulation": sim, "methods": ["cma"]})


def test_every_computation_states_and_gives_its_estimate() -> None:
    for name in ("simulation", "compare", "stability", *SWEEP_KINDS, "study"):
        c = COMPUTATIONS[name]
        assert c.estimate is not None, name
        for example in c.examples.values():
            cost = c.estimate(registry.parse(name, example["value"]))
            assert cost is not None and 0 < cost.units <= cost.bound, name
            stated = f"{cost.bound:,}", f"{cost.bound:g}", "500 times the base's bound"
            assert any(s in c.cost for s in stated), (name, c.cost)
    frf = COMPUTATIONS["frequency_response"]
    assert frf.estimate is not None


def test_a_study_is_bounded_by_its_cases_times_the_costliest_case() -> None:
    """A grid whose one overridden count is large: the costliest case (the base at that
    count) times the cases is over the study's bound; the same grid with small counts is
    accepted."""
    base = _simulation(output={"positions": _positions(4)})
    grid = {"pipe.M2": [1e-5 * (1 + i / 1000) for i in range(1000)]}
    big = {
        "base": {"kind": "simulation", "spec": base},
        "grid": {**grid, "time.samples": [101, 200_001]},
    }
    field, message = _refusal("study", big)
    assert field == "grid"
    assert "2000 cases" in message and "time.samples = 200001" in message
    assert "study budget" in message and re.search(r"at most \d+ cases", message)
    small = {**big, "grid": {**grid, "time.samples": [101, 201]}}
    assert registry.parse("study", small)


def test_a_study_of_many_cases_of_a_large_base_is_refused() -> None:
    base = _simulation(time={"t_end": 1.0, "samples": 200_001})
    body = {"base": {"kind": "simulation", "spec": base}, "cases": [{}] * 10_000}
    field, message = _refusal("study", body)
    assert field == "cases" and "10000 cases" in message


# -- a bending stiffness that underflows -------------------------------------------------

TINY_EI = {"E": 1e-200, "I": 1e-200}


@pytest.mark.parametrize("method", sorted(SOLVERS))
def test_every_method_refuses_an_underflowing_bending_stiffness(method: str) -> None:
    body = _simulation(method=method, pipe={**PAPER_EXAMPLE["pipe"], **TINY_EI})
    field, message = _refusal("simulation", body)
    assert field == "pipe.E"
    assert "pipe.I" in message and "underflows" in message


def test_every_analysis_refuses_an_underflowing_bending_stiffness() -> None:
    pipe = {**PAPER_EXAMPLE["pipe"], **TINY_EI}
    sim = _simulation(pipe=pipe)
    assert _refusal("compare", {"simulation": sim})[0] == "simulation.pipe.E"
    for name in ("stability", *[k for k in SWEEP_KINDS if k != "beta_map"], "frequency_response"):
        example = next(iter(COMPUTATIONS[name].examples.values()))["value"]
        field, _ = _refusal(name, {**example, "pipe": pipe})
        assert field == "pipe.E", name


def test_the_librarys_pipe_refuses_it_too() -> None:
    with pytest.raises(InvalidInput, match="underflows") as info:
        Pipe(E=1e-200, I=1e-200, L=1.0, M1=1.0, M2=0.0)
    assert info.value.parameter == "E"
    assert Pipe(E=1e-150, I=1e-150, L=1.0, M1=1.0, M2=0.0).EI == pytest.approx(1e-300)
