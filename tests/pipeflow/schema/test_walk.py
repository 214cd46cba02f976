"""The walk of a flow velocity below the service, pinned file by file (issue 33, "the walks
shorter").

Counted at the grain of the issue's audit: a hop hands the velocity, or an object holding
it, to a function in another file; a crossing is a hop into another layer (computations ->
schema -> library).  Two stacks are read, each at the moment the velocity arrives:

- the conversion: where the library's profile object (:class:`pipeflow.profiles.Polynomial`)
  is built from the validated request;
- the evaluation: where S(t)'s coefficients first read v(t)
  (:meth:`pipeflow.loading.Loading.coefficients`).

A layer added on the way (or one taken away) changes a stack and fails the test: update
the chain here and the counts in the issue's closing note together.  The service's part of
the walk (body, key, engine, task) is :mod:`tests.service.test_request_walk`'s.
"""

from __future__ import annotations

import traceback
from pathlib import Path
from typing import Any

import pytest

from pipeflow import loading as loading_module
from pipeflow import profiles
from pipeflow.computations.registry import COMPUTATIONS
from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec

ROOT = Path(__file__).resolve().parents[3]


def _files(stack: list[traceback.FrameSummary]) -> list[str]:
    """The package files on ``stack`` (outermost first) from the registry down, each
    consecutive run of frames in one file counted once (a hop is a change of file)."""
    names = [
        str(Path(f.filename).resolve().relative_to(ROOT))
        for f in stack
        if Path(f.filename).resolve().is_relative_to(ROOT / "pipeflow")
    ]
    start = names.index("pipeflow/computations/registry.py")
    out: list[str] = []
    for name in names[start:]:
        if not out or out[-1] != name:
            out.append(name)
    return out


def test_velocity_walk_below_the_service(monkeypatch: pytest.MonkeyPatch) -> None:
    stacks: dict[str, list[traceback.FrameSummary]] = {}
    built_count = [0]
    polynomial_init = profiles.Polynomial.__init__
    coefficients = loading_module.Loading.coefficients

    def built(self: Any, *args: Any, **kw: Any) -> None:
        stacks.setdefault("conversion", traceback.extract_stack()[:-1])
        built_count[0] += 1
        polynomial_init(self, *args, **kw)

    def evaluated(self: Any, t: Any) -> Any:
        stacks.setdefault("evaluation", traceback.extract_stack()[:-1])
        return coefficients(self, t)

    spec = SimulationSpec.model_validate(
        {
            "pipe": PAPER_EXAMPLE["pipe"],
            "flow": {"velocity": {"kind": "polynomial", "coefficients": [0.0, 0.4]}},
            "rotation": {"omega0": {"kind": "constant", "value": 10.0}},
            "modes": 2,
            "time": {"t_end": 0.02, "samples": 5},
        }
    )
    monkeypatch.setattr(profiles.Polynomial, "__init__", built)
    monkeypatch.setattr(loading_module.Loading, "coefficients", evaluated)
    COMPUTATIONS["simulation"].execute(spec)

    # the request becomes library objects in the schema's own conversion:
    # computations -> schema -> library
    assert _files(stacks["conversion"]) == [
        "pipeflow/computations/registry.py",  # Computation.execute
        "pipeflow/computations/simulation.py",  # run_simulation, simulate_spec
        "pipeflow/schema/simulation.py",  # SimulationSpec.to_simulation
        "pipeflow/schema/profiles.py",  # Polynomial.to_profile
    ]  # -> the library's Polynomial (pipeflow/profiles.py)
    assert built_count == [1]  # converted once
    # then the library carries the profile to S(t): computations -> library
    assert _files(stacks["evaluation"]) == [
        "pipeflow/computations/registry.py",  # Computation.execute
        "pipeflow/computations/simulation.py",  # run_simulation, simulate_spec
        # simulate: builds Loading (pipeflow/loading.py) and Problem (solvers/base.py), asks
        # auto (solvers/auto.py, Auto.choose: magnus for a time-variant flow), then runs it
        "pipeflow/simulation.py",
        "pipeflow/solvers/base.py",  # Solver.solve (timing, counters, impulses)
        "pipeflow/solvers/magnus/control.py",  # Magnus._solve_impl, step_control
        "pipeflow/solvers/magnus/generator.py",  # MagnusGenerator.coefficients
    ]  # -> Loading.coefficients (pipeflow/loading.py) -> Polynomial.value: v(t) in S(t)
