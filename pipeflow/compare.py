"""Run one simulation with several methods and compare their cost and their answers.

The user-side version of the paper's Tables 1 and 2 (CMA against RK4 CPU time), on any
case: :func:`compare` runs the same :class:`~pipeflow.simulation.Simulation` with each
method, times it, and reports each method's difference from the most accurate one.  It is
a pure function returning a JSON-ready dictionary (no I/O); its request model is
:class:`pipeflow.schema.simulation.CompareSpec` (``POST /v1/compare``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from pipeflow._types import Progress
from pipeflow.diagnostics import summary
from pipeflow.errors import InvalidInput
from pipeflow.model import build_model
from pipeflow.simulation import Result, Simulation, simulate
from pipeflow.solvers import SOLVERS
from pipeflow.solvers.base import relative_difference

MAX_METHODS = 8


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
) -> dict[str, Any]:
    """Run ``sim`` with each of ``methods`` (default: :func:`default_methods`, every
    registered method but ``reference`` and ``auto``) and compare.

    Returns a JSON-ready dictionary (:class:`pipeflow.schema.results.CompareResponse`)::

        {"baseline": name of the most accurate method (smallest estimated error),
         "methods": [{"method", "method_used", "status", "solve_seconds" [s], "wall_seconds" [s],
                      "speedup_vs_slowest" [-], "estimated_relative_error" [-],
                      "difference_from_baseline" [-] (balanced state),
                      "tip_difference_from_baseline" [-], "warnings", "diagnostics"}, ...],
         "samples", "modes", "t_end" [s]}

    Differences are relative: max over time of the difference over max over time of the
    baseline, on the balanced state (modal displacements and scaled velocities) and on the
    tip displacement.  Where a response overflowed, only the common finite part is compared.
    """
    from pipeflow.schema import results as r  # the contract, imported on first use

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

    accuracy = [_accuracy(r) for r, _ in runs]
    best = int(np.argmin(accuracy))
    base = runs[best][0]
    base_z = model.to_balanced(base.d, base.ddot)
    solve_times = [float(r.diagnostics.get("solve_seconds", wall)) for r, wall in runs]
    slowest = max(solve_times)
    rows = []
    for (result, wall), solve_s, acc in zip(runs, solve_times, accuracy, strict=True):
        z = model.to_balanced(result.d, result.ddot)
        n = min(z.shape[0], base_z.shape[0])
        rows.append(
            r.document(
                r.MethodComparison,
                method=result.simulation.method,
                method_used=result.method_used,
                status=str(result.status),
                solve_seconds=solve_s,
                wall_seconds=wall,
                speedup_vs_slowest=slowest / solve_s if solve_s > 0 else None,
                estimated_relative_error=acc if math.isfinite(acc) else None,
                difference_from_baseline=relative_difference(z[:n], base_z[:n]),
                tip_difference_from_baseline=relative_difference(
                    result.tip_displacement[:n], base.tip_displacement[:n]
                ),
                compared_samples=n,
                warnings=list(result.warnings),
                diagnostics=summary(result.to_dict()["diagnostics"]),
            )
        )
    return r.document(
        r.CompareResponse,
        baseline=base.simulation.method,
        methods=rows,
        samples=sim.samples,
        modes=sim.modes,
        t_end=sim.t_end,
    )
