"""How far to trust a result: an error estimate for every method, added to its diagnostics.

The paper's CMA is exact only when the state matrices S(t) commute (constant coefficients);
for v = a t, a t^2 or a varying spin it is the first Magnus term and carries an error the
solver itself cannot see (physics notes, section 2).  RK4's error depends on its step.
:func:`add_error_estimate` measures both against an independent, accurate solution: a
``magnus`` run on at most :data:`CHECK_SAMPLES` of the output times, first with a fixed
:data:`CHECK_STEPS` steps (its own error estimated by step doubling), repeated to a
tolerance of :data:`RESOLUTION_FRACTION` of the measured error (at least
:data:`CHECK_TOLERANCE`) only when that first run cannot resolve it.
Methods that control their own error (``magnus``, ``reference``) report it themselves,
and ``cma`` on constant coefficients knows it is exact: each solver says which applies.

Every estimate is a relative error of the balanced state (modal displacements and
velocities over the reference frequencies, in metres), max over time of the difference
divided by max over time of the solution [-].  Above :data:`WARN_THRESHOLD` a warning says
so, and which method to use instead.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pipeflow.errors import PipeflowError
from pipeflow.solvers import SOLVERS, Problem, Solver, SolverOutput
from pipeflow.solvers.base import relative_difference

#: relative error above which a result carries a warning [-]
WARN_THRESHOLD = 1e-4
#: the yardstick resolves errors down to this (relative) [-]
CHECK_TOLERANCE = 1e-6
#: steps of the first, fixed-step yardstick run over the whole run: on the paper's example
#: (10 modes, 1 s) its error is ~4e-6, against cma errors of 3e-3..6e-2 on time-variant
#: input
CHECK_STEPS = 256
#: the yardstick's own error must be below this fraction of the error it measures, or the
#: check is repeated to that tolerance (so an estimate is good to ~10%)
RESOLUTION_FRACTION = 0.1
#: at most this many output times are checked (evenly spread, first and last included)
CHECK_SAMPLES = 257
#: the method that serves as the yardstick
CHECK_METHOD = "magnus"


def check_indices(n_times: int, samples: int = CHECK_SAMPLES) -> NDArray[np.int64]:
    """Indices of at most ``samples`` output times, evenly spread, including both ends."""
    if n_times <= samples:
        return np.arange(n_times)
    return np.unique(np.linspace(0, n_times - 1, samples).round().astype(np.int64))


def add_error_estimate(
    solver: Solver, problem: Problem, out: SolverOutput, threshold: float = WARN_THRESHOLD
) -> None:
    """Add ``estimated_relative_error`` (and how it was obtained) to the output ``out`` of
    ``solver``; warn above ``threshold``.  Mutates ``out.diagnostics`` and ``out.warnings``.

    The solver says what applies: it estimates its own error
    (``Solver.estimates_own_error``), knows it exactly (``Solver.exact_error``), or is
    measured against a :data:`CHECK_METHOD` run here."""
    diag = out.diagnostics
    if solver.estimates_own_error:
        if "estimated_relative_error" in diag:
            _warn(solver, float(diag["estimated_relative_error"]), threshold, out)
        return
    t0 = time.perf_counter()
    exact = solver.exact_error(problem, out)
    if exact is not None:
        diag["estimated_relative_error"], diag["error_estimate_method"] = exact
        return
    finite = np.all(np.isfinite(out.z), axis=1)
    last = int(np.argmin(finite)) if not finite.all() else out.z.shape[0]
    if last < 2:
        diag["error_estimate_method"] = "unavailable: the response overflowed at once"
        return
    idx = check_indices(last)
    t_check = problem.t[idx]
    try:
        # first a fixed-step yardstick (CHECK_STEPS steps, its own error estimated by
        # step doubling); only where it cannot resolve the error it measures, a run to
        # a tolerance of RESOLUTION_FRACTION of that error
        # (the sampled intervals are uneven by one output step: a step no shorter than the
        # longest keeps one step per interval instead of two on the longer ones)
        step = max(float(t_check[-1]) / CHECK_STEPS, float(np.max(np.diff(t_check))))
        check = _yardstick(problem, t_check, step=step)
        estimate = relative_difference(out.z[idx], check.z, problem.model.size)
        resolution = float(check.diagnostics.get("estimated_relative_error", 0.0))
        if resolution > max(CHECK_TOLERANCE, RESOLUTION_FRACTION * estimate):
            tol = max(CHECK_TOLERANCE, RESOLUTION_FRACTION * estimate)
            check = _yardstick(problem, t_check, tolerance=min(tol, 0.5))
            estimate = relative_difference(out.z[idx], check.z, problem.model.size)
            resolution = float(check.diagnostics.get("estimated_relative_error", 0.0))
    except PipeflowError as exc:
        diag["error_estimate_method"] = f"unavailable: {exc.message}"
        return
    diag["estimated_relative_error"] = estimate
    diag["error_estimate_method"] = (
        f"comparison with a {CHECK_METHOD} run (estimated error {resolution:.2g}) at "
        f"{idx.size} of the output times"
    )
    diag["error_estimate_resolution"] = resolution
    # the same on the tip displacement u(L, t), the quantity most users plot; it is often
    # smaller than the state error (higher modes carry the state error, little of the tip)
    model = problem.model
    tip_check = model.from_balanced(check.z[:, : model.size])[0] @ model.tip
    tip_out = model.from_balanced(out.z[idx])[0] @ model.tip
    if np.any(tip_check != 0):
        diag["estimated_tip_relative_error"] = relative_difference(tip_out, tip_check)
    diag["error_estimate_seconds"] = time.perf_counter() - t0
    _warn(solver, estimate, threshold, out)


def _yardstick(
    problem: Problem, t: NDArray[np.float64], step: float | None = None, tolerance: float = 1e-6
) -> SolverOutput:
    """A :data:`CHECK_METHOD` run of ``problem`` at the output times ``t`` [s], with a fixed
    ``step`` [s] or to ``tolerance`` [-]."""
    options = replace(problem.options, step=step, tolerance=tolerance)
    sub = Problem(problem.model, problem.loading, problem.z0, t, options, loads=problem.loads)
    return SOLVERS[CHECK_METHOD].solve(sub)


def _warn(solver: Solver, estimate: float, threshold: float, out: SolverOutput) -> None:
    if not (estimate > threshold or math.isnan(estimate)):
        return
    out.warnings.append(
        f"estimated relative error of this {solver.name} result is {estimate:.2g}, above "
        f"{threshold:g}: {solver.error_advice}"
    )


def summary(diagnostics: dict[str, Any]) -> dict[str, Any]:
    """The trust-related entries of a diagnostics dictionary (for tables and comparisons)."""
    keys = (
        "estimated_relative_error",
        "estimated_tip_relative_error",
        "error_estimate_method",
        "eigenvector_condition_max",
        "stability_margin",
        "steps",
    )
    return {k: diagnostics[k] for k in keys if k in diagnostics}
