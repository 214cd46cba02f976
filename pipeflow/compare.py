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

from pipeflow.diagnostics import summary
from pipeflow.errors import InvalidInput
from pipeflow.model import build_model
from pipeflow.simulation import Result, Simulation, simulate
from pipeflow.solvers import SOLVERS
from pipeflow.solvers.base import ProgressCallback

#: the reference integrator's error is taken as this multiple of its rtol when ranking
#: (measured: rtol 1e-12 gives ~3e-10 on the paper's example)
REFERENCE_ERROR_PER_RTOL = 300.0
MAX_METHODS = 8


def _accuracy(result: Result) -> float:
    """Claimed relative error of a result [-], used to pick the most accurate method."""
    d = result.diagnostics
    if result.simulation.method == "reference":
        return REFERENCE_ERROR_PER_RTOL * float(result.simulation.options.rtol)
    value = d.get("estimated_relative_error")
    if isinstance(value, int | float) and math.isfinite(value):
        return float(value)
    return math.inf


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| / max |b| over the rows (states) or entries (tip) [-]."""
    if a.ndim == 1:
        scale = float(np.max(np.abs(b))) if b.size else 0.0
        diff = float(np.max(np.abs(a - b))) if b.size else 0.0
    else:
        scale = float(np.max(np.linalg.norm(b, axis=1))) if b.size else 0.0
        diff = float(np.max(np.linalg.norm(a - b, axis=1))) if b.size else 0.0
    return diff / scale if scale > 0 else diff


def compare(
    sim: Simulation,
    methods: Sequence[str] | None = None,
    progress: ProgressCallback | None = None,
) -> dict[str, Any]:
    """Run ``sim`` with each of ``methods`` (default: every registered method but
    ``reference``) and compare.

    Returns a JSON-ready dictionary::

        {"baseline": name of the most accurate method (smallest estimated error),
         "methods": [{"method", "status", "solve_seconds" [s], "wall_seconds" [s],
                      "speedup_vs_slowest" [-], "estimated_relative_error" [-],
                      "difference_from_baseline" [-] (balanced state),
                      "tip_difference_from_baseline" [-], "warnings", "diagnostics"}, ...],
         "samples", "modes", "t_end" [s]}

    Differences are relative: max over time of the difference over max over time of the
    baseline, on the balanced state (modal displacements and scaled velocities) and on the
    tip displacement.  Where a response overflowed, only the common finite part is compared.
    """
    names = list(methods) if methods is not None else [m for m in SOLVERS if m != "reference"]
    if not names:
        raise InvalidInput("give at least one method to compare", field="methods")
    if len(names) > MAX_METHODS or len(set(names)) != len(names):
        raise InvalidInput(
            f"give at most {MAX_METHODS} distinct methods to compare", field="methods"
        )
    for i, name in enumerate(names):
        if name not in SOLVERS:
            raise InvalidInput(
                f"unknown method {name!r}; choose from {', '.join(sorted(SOLVERS))}",
                field=f"methods.{i}",
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
            {
                "method": result.simulation.method,
                "status": result.status,
                "solve_seconds": solve_s,
                "wall_seconds": wall,
                "speedup_vs_slowest": slowest / solve_s if solve_s > 0 else None,
                "estimated_relative_error": acc if math.isfinite(acc) else None,
                "difference_from_baseline": _relative(z[:n], base_z[:n]),
                "tip_difference_from_baseline": _relative(
                    result.tip_displacement[:n], base.tip_displacement[:n]
                ),
                "compared_samples": n,
                "warnings": list(result.warnings),
                "diagnostics": summary(result.to_dict()["diagnostics"]),
            }
        )
    return {
        "baseline": base.simulation.method,
        "methods": rows,
        "samples": sim.samples,
        "modes": sim.modes,
        "t_end": sim.t_end,
    }
