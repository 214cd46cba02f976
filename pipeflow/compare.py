"""Run one simulation with several methods and compare their cost and their answers.

The user-side version of the paper's Tables 1 and 2 (CMA against RK4 CPU time), on any
case: :func:`compare` runs the same :class:`~pipeflow.simulation.Simulation` with each
method, times it, and reports each method's difference from the most accurate one.  It is
a pure function returning a :class:`Comparison` (no I/O); its request model is
:class:`pipeflow.schema.simulation.CompareSpec` (``POST /v1/compare``), its JSON form
:func:`pipeflow.computations.documents.compare`.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from pipeflow._types import Progress
from pipeflow.errors import InvalidInput
from pipeflow.model import build_model
from pipeflow.simulation import Result, Simulation, simulate
from pipeflow.solvers import SOLVERS
from pipeflow.solvers.base import relative_difference

MAX_METHODS = 8


@dataclass(frozen=True)
class MethodRun:
    """One method's run in a :class:`Comparison` (SI units).

    result : the simulation it ran (``result.simulation.method``: the method asked).
    wall_seconds : wall-clock time of :func:`~pipeflow.simulation.simulate` [s].
    solve_seconds : the solver's own time (``diagnostics["solve_seconds"]``, else the wall
        time) [s].
    estimated_relative_error : the error the solver claims [-] (``Solver.claimed_error``;
        inf when it claims none).
    difference_from_baseline : max over time of the difference of the balanced state (modal
        displacements and scaled velocities) from the baseline's, over the baseline's max [-].
    tip_difference_from_baseline : the same on the tip displacement [-].
    compared_samples : the samples both runs have (a run that overflowed has fewer).
    """

    result: Result
    wall_seconds: float
    solve_seconds: float
    estimated_relative_error: float
    difference_from_baseline: float
    tip_difference_from_baseline: float
    compared_samples: int


@dataclass(frozen=True)
class Comparison:
    """Result of :func:`compare`: one run per method, in the order asked.

    simulation : the case compared (its ``method`` aside); baseline : the run of the most
    accurate method (the smallest claimed error), which the differences are measured from.
    """

    simulation: Simulation
    runs: list[MethodRun]
    baseline: Result


def _accuracy(result: Result) -> float:
    """Claimed relative error of a result [-], used to pick the most accurate method: the
    solver that ran it says (``Solver.claimed_error``)."""
    solver = SOLVERS[result.method_used]
    return solver.claimed_error(result.simulation.options, result.diagnostics)


def default_methods() -> list[str]:
    """The methods :func:`compare` runs when given none (``Solver.compared_by_default``)."""
    return [name for name, solver in SOLVERS.items() if solver.compared_by_default]


def compare(
    sim: Simulation,
    methods: Sequence[str] | None = None,
    progress: Progress | None = None,
) -> Comparison:
    """Run ``sim`` with each of ``methods`` (default: :func:`default_methods`, every
    registered method but ``reference`` and ``auto``) and compare (:class:`Comparison`:
    each method's times, claimed error and difference from the most accurate one).

    Differences are relative: max over time of the difference over max over time of the
    baseline, on the balanced state (modal displacements and scaled velocities) and on the
    tip displacement.  Where a response overflowed, only the common finite part is compared.
    """

    names = list(methods) if methods is not None else default_methods()
    if not names:
        raise InvalidInput("give at least one method to compare", parameter="methods")
    if len(names) > MAX_METHODS or len(set(names)) != len(names):
        raise InvalidInput(
            f"give at most {MAX_METHODS} distinct methods to compare", parameter="methods"
        )
    for i, name in enumerate(names):
        if name not in SOLVERS:
            raise InvalidInput(
                f"methods[{i}]: unknown method {name!r}; choose from {', '.join(sorted(SOLVERS))}",
                parameter="methods",
            )
    model = build_model(sim.pipe, sim.modes, sim.quadrature_order)
    runs: list[tuple[Result, float]] = []
    for i, name in enumerate(names):

        def part(fraction: float, i: int = i) -> None:
            if progress is not None:
                progress((i + fraction) / len(names))

        t0 = time.perf_counter()
        result = simulate(replace(sim, method=name), progress=part)
        runs.append((result, time.perf_counter() - t0))

    accuracy = [_accuracy(result) for result, _ in runs]
    base = runs[int(np.argmin(accuracy))][0]
    base_z = model.to_balanced(base.d, base.ddot)
    rows = []
    for (result, wall), acc in zip(runs, accuracy, strict=True):
        z = model.to_balanced(result.d, result.ddot)
        n = min(z.shape[0], base_z.shape[0])
        rows.append(
            MethodRun(
                result=result,
                wall_seconds=wall,
                solve_seconds=float(result.diagnostics.get("solve_seconds", wall)),
                estimated_relative_error=acc,
                difference_from_baseline=relative_difference(z[:n], base_z[:n]),
                tip_difference_from_baseline=relative_difference(
                    result.tip_displacement[:n], base.tip_displacement[:n]
                ),
                compared_samples=n,
            )
        )
    return Comparison(simulation=sim, runs=rows, baseline=base)
